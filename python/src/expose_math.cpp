// Pose errors, rotations, the filters of eqs. 5 and 9, and the placement of eqs. 18-20.
#include "expose.hpp"

namespace vmpy {

using namespace nb::literals;

namespace {

struct PlacementResult {
  JointVector theta;
  TrackResult result;
};

void expose_rotations_and_filters(nb::module_& m) {
  m.def("pose_error", [](nb::handle a, nb::handle b) {
        return Vector6(pose_error(pose_arg("T_a", a), pose_arg("T_b", b)));
      }, "T_a"_a, "T_b"_a,
      "Pose error e = [p_a - p_b; log(R_a R_b^T)] (6,): metres, then a rotation vector in world "
      "axes [rad].");
  m.def("so3_log", [](nb::handle R) { return Eigen::Vector3d(so3_log(matrix_arg("R", R, 3, 3))); },
        "R"_a, "Rotation vector (3,) of a rotation matrix (3, 3).");
  m.def("so3_exp", [](nb::handle w) { return Eigen::Matrix3d(so3_exp(vector_arg("w", w, 3))); },
        "w"_a, "Rotation matrix (3, 3) of a rotation vector (3,).");
  auto filter = [](bool range) {
    return [range](nb::handle J, nb::handle W) {
      const Eigen::MatrixXd Jm = matrix_arg("J", J, 6, -1);
      if (Jm.cols() < 1 || Jm.cols() > kMaxDof) {
        throw nb::value_error(("J: expected 1 to " + std::to_string(kMaxDof) + " columns, got " +
                               std::to_string(Jm.cols())).c_str());
      }
      const bool diagonal = nb::cast<long>(nb::module_::import_("numpy").attr("ndim")(W)) == 1;
      const Matrix6 Wm = diagonal ? Matrix6(Vector6(vector_arg("W", W, 6)).asDiagonal())
                                  : Matrix6(matrix_arg("W", W, 6, 6));
      require_finite("W", Eigen::Map<const Eigen::VectorXd>(Wm.data(), 36));
      const Jacobian Jv = Jm;
      return Eigen::MatrixXd(range ? range_filter(Jv, Wm) : null_filter(Jv, Wm));
    };
  };
  m.def("range_filter", filter(true), "J"_a, "W"_a,
        "Range-space filter P(W) = W J (J^T W J)^+ J^T (6, 6) (eq. 5). J (6, n); W a (6,) "
        "diagonal or a (6, 6) symmetric positive semi-definite matrix.");
  m.def("null_filter", filter(false), "J"_a, "W"_a, "Null-space filter N(W) = I - P(W) (eq. 9).");
}

void expose_placement(nb::module_& m) {
  m.def("reach", [](const Device& device, nb::handle target, nb::handle seeds, double length_scale,
                    int max_iterations) {
        std::vector<JointVector> s;
        for (nb::handle h : seeds) s.push_back(joints_arg("seeds", h, device.dof()));
        const DevicePose r = reach(device, pose_arg("target", target), s, length_scale, max_iterations);
        return nb::make_tuple(Eigen::VectorXd(r.q), r.error, r.seed);
      }, "device"_a, "target"_a, "seeds"_a, "length_scale"_a = 0.1, "max_iterations"_a = 200,
      "The device's joint values (dof,) within its limits whose handle pose is nearest the "
      "target (4, 4), weighted [1 1 1 L^2 L^2 L^2]: Levenberg-Marquardt on the device's "
      "kinematics from each seed (dof,) in turn, the first that reaches it kept, else the "
      "nearest. Returns (q, pose_error(target, forward(q)) (6,), the seed's index).");

  nb::class_<PlacementResult>(m, "TrackResult", "Result of track().")
      .def_prop_ro("theta", [](const PlacementResult& r) { return Eigen::VectorXd(r.theta); },
                   "Mechanism joint values (dof,).")
      .def_prop_ro("iterations", [](const PlacementResult& r) { return r.result.iterations; })
      .def_prop_ro("residual", [](const PlacementResult& r) { return r.result.residual; },
                   "sqrt(e^T W e) at theta")
      .def_prop_ro("converged", [](const PlacementResult& r) { return r.result.converged; })
      .def_prop_ro("active", [](const PlacementResult& r) {
            Eigen::Matrix<bool, Eigen::Dynamic, 1> a(r.theta.size());
            for (Eigen::Index i = 0; i < a.size(); ++i) a[i] = ((r.result.active >> i) & 1u) != 0;
            return a;
          }, "Joints held at a limit that acts (dof,) of bool.")
      .def("__repr__", [](const PlacementResult& r) {
        return "TrackResult(theta=" + format_vector(r.theta) + ", iterations=" +
               std::to_string(r.result.iterations) + ", residual=" +
               std::to_string(r.result.residual) + ", converged=" +
               (r.result.converged ? "True" : "False") + ")";
      });

  m.def("track", [](const Mechanism& mech, nb::handle target, nb::handle theta0,
                    nb::handle weights, int max_iterations, bool closed_form) {
        const Pose T = pose_arg("target_pose", target);
        const JointVector th0 = theta0.is_none() ? mech.home() : joints_arg("theta0", theta0, mech.dof());
        require_finite("theta0", th0);
        const double L = mech.length_scale();
        const Vector6 W = weights.is_none() ? (Vector6() << 1, 1, 1, L * L, L * L, L * L).finished()
                                            : Vector6(vector_arg("weights", weights, 6));
        require_non_negative("weights", W);
        if (max_iterations < 1) {
          throw nb::value_error(("max_iterations: expected >= 1, got " + std::to_string(max_iterations)).c_str());
        }
        TrackOptions opts;
        opts.max_iterations = max_iterations;
        opts.closed_form = closed_form;
        PlacementResult out;
        out.result = track(mech, T, th0, W, opts, out.theta);
        return out;
      }, "mechanism"_a, "target_pose"_a, "theta0"_a = nb::none(), "weights"_a = nb::none(),
      "max_iterations"_a = 20, "closed_form"_a = true,
      "The placement of eqs. 18-20: theta minimising e^T diag(W) e with e = "
      "pose_error(target_pose, mechanism.forward(theta)), within the joint limits; theta0 (dof,) "
      "(the warm start) defaults to the mechanism's home, weights (6,) to [1 1 1 L^2 L^2 L^2]. "
      "The mechanism's closed form where it has one (Probe, PointPivot with weights isotropic in "
      "position and in rotation) unless closed_form=False, else weighted Gauss-Newton. Returns "
      ".theta, .iterations (0: closed form), .residual, .converged, .active (joints held at a "
      "limit).");
}

}  // namespace

void expose_math(nb::module_& m) {
  expose_rotations_and_filters(m);
  expose_placement(m);
}

}  // namespace vmpy
