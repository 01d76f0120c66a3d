// The C API's shapes (NURBS curves and surfaces, sphere, cylinder, plane), the mechanisms on
// them (SurfaceProbe, CurveGuide, HandlePath) and mechanism sets: the same cycle as the C++
// classes built from the same data, errors that name the bad parameter, shapes that may be
// destroyed as soon as a controller holds them.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "c_api_support.hpp"
#include "cycle_scenes.hpp"
#include "test_support.hpp"
#include "virtmech.h"

using namespace virtmech;

namespace vmtest {

// c_api_support.hpp's helpers.

vm_shape* c_nurbs_curve(const NurbsCurve& c) {
  const int n = c.size();
  std::vector<double> P(static_cast<size_t>(3 * n));
  const Eigen::MatrixX3d cp = c.control_points();
  for (int i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) P[static_cast<size_t>(3 * i + a)] = cp(i, a);
  const Eigen::VectorXd w = c.weights();
  vm_shape* s = nullptr;
  char err[256];
  if (vm_nurbs_curve_create(P.data(), w.data(), n, c.knots().data(), c.degree(), &s, err,
                            sizeof err) != VM_OK) {
    throw std::runtime_error(err);
  }
  return s;
}

vm_shape* c_nurbs_surface(const NurbsSurface& f) {
  const int nu = f.size_u(), nv = f.size_v();
  std::vector<double> P(static_cast<size_t>(3 * nu * nv)), W(static_cast<size_t>(nu * nv));
  const Eigen::MatrixX3d cp = f.control_points();
  const Eigen::MatrixXd w = f.weights();
  for (int i = 0; i < nu * nv; ++i)
    for (int a = 0; a < 3; ++a) P[static_cast<size_t>(3 * i + a)] = cp(i, a);
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) W[static_cast<size_t>(i * nv + j)] = w(i, j);
  vm_shape* s = nullptr;
  char err[256];
  if (vm_nurbs_surface_create(P.data(), W.data(), nu, nv, f.knots_u().data(), f.knots_v().data(),
                              f.degree_u(), f.degree_v(), &s, err, sizeof err) != VM_OK) {
    throw std::runtime_error(err);
  }
  return s;
}

// vmtest::make_set() through the C API: the same members, settings and device.
vm_mechanism_set* c_make_set(int capacity) {
  vm_device_desc dev;
  vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
  vm_set_settings ss;
  vm_set_settings_init(&ss);
  ss.snap_distance = 0.01;
  ss.release_distance = 0.02;
  vm_mechanism_set* set = nullptr;
  char err[256];
  if (vm_mechanism_set_create(&dev, capacity, &ss, &set, err, sizeof err) != VM_OK) {
    throw std::runtime_error(err);
  }
  vm_settings s;
  vm_settings_init(&s);
  s.watchdog_s = vmtest::cycle_settings().watchdog_s;
  vm_shape* patch = c_nurbs_surface(*vmtest::test_patch(Eigen::Vector3d(0, 0, -0.12)));
  vm_shape* letter = c_nurbs_curve(*vmtest::test_letter(Eigen::Vector3d(0, 0, -0.1)));
  vm_shape* letter2 = c_nurbs_curve(*vmtest::test_letter(Eigen::Vector3d(0.02, 0.01, -0.08)));
  vm_mechanism_desc m[4];
  vm_mechanism_desc_init(&m[0], VM_MECHANISM_SURFACE_PROBE);
  m[0].shape = patch;
  vm_mechanism_desc_init(&m[1], VM_MECHANISM_PROBE);
  m[1].point[1] = -0.02;
  m[1].normal[1] = 1.0;
  m[1].normal[2] = 0.0;
  m[1].unilateral = 1;
  vm_mechanism_desc_init(&m[2], VM_MECHANISM_CURVE_GUIDE);
  m[2].shape = letter;
  vm_mechanism_desc_init(&m[3], VM_MECHANISM_CURVE_GUIDE);
  m[3].shape = letter2;
  for (int i = 0; i < 4; ++i) {
    const int index = vm_mechanism_set_add(set, &m[i], &s, err, sizeof err);
    if (index != i) throw std::runtime_error(std::to_string(index) + ": " + err);
  }
  vm_shape_destroy(patch);
  vm_shape_destroy(letter);
  vm_shape_destroy(letter2);
  return set;
}

}  // namespace vmtest

namespace {

using vmtest::c_make_set;
using vmtest::c_nurbs_curve;
using vmtest::c_nurbs_surface;

void set3(double* out, const Eigen::Vector3d& v) {
  for (int a = 0; a < 3; ++a) out[a] = v[a];
}

// A C shape mechanism and the C++ one built from the same data.
struct ShapeCase {
  std::string name;
  vm_shape* shape;  // destroyed by the test right after the controller is created
  vm_mechanism_desc desc;
  std::shared_ptr<const Mechanism> cpp;
};

std::vector<ShapeCase> shape_cases() {
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), z = Eigen::Vector3d::UnitZ();
  std::vector<ShapeCase> out;
  auto desc = [](vm_mechanism_type type, vm_shape* s) {
    vm_mechanism_desc m;
    vm_mechanism_desc_init(&m, type);
    m.shape = s;
    return m;
  };
  {
    const auto patch = vmtest::test_patch(Eigen::Vector3d(0, 0, -0.12));
    for (int u : {0, 1}) {
      vm_mechanism_desc m = desc(VM_MECHANISM_SURFACE_PROBE, c_nurbs_surface(*patch));
      m.length = 0.1;
      m.unilateral = u;
      out.push_back({u ? "SurfaceProbeNurbsUnilateral" : "SurfaceProbeNurbs",
                     const_cast<vm_shape*>(m.shape), m,
                     std::make_shared<SurfaceProbe>(patch, 0.1, u == 1)});
    }
  }
  {
    const Eigen::Vector3d c(0, -0.05, -0.1);
    vm_shape* s = nullptr;
    double cc[3], ax[3];
    set3(cc, c);
    set3(ax, x);
    char err[256];
    const int rc = vm_sphere_create(cc, 0.04, ax, &s, err, sizeof err);
    EXPECT_EQ(rc, VM_OK) << err;
    vm_mechanism_desc m = desc(VM_MECHANISM_SURFACE_PROBE, s);
    m.unilateral = 1;
    out.push_back({"SurfaceProbeSphereUnilateral", s, m,
                   std::make_shared<SurfaceProbe>(std::make_shared<Sphere>(c, 0.04, x), 0.1, true)});
  }
  {
    const Eigen::Vector3d p(0, -0.02, -0.15), d = Eigen::Vector3d(1, 0.2, 0).normalized();
    double pp[3], dd[3];
    set3(pp, p);
    set3(dd, d);
    vm_shape* s = nullptr;
    EXPECT_EQ(vm_cylinder_create(pp, dd, 0.03, &s, nullptr, 0), VM_OK);
    out.push_back({"SurfaceProbeCylinder", s, desc(VM_MECHANISM_SURFACE_PROBE, s),
                   std::make_shared<SurfaceProbe>(std::make_shared<Cylinder>(p, d, 0.03), 0.1)});
  }
  {
    const Eigen::Vector3d p(0, -0.02, 0), n = Eigen::Vector3d(0, 1, 0.2).normalized();
    double pp[3], nn[3];
    set3(pp, p);
    set3(nn, n);
    vm_shape* s = nullptr;
    EXPECT_EQ(vm_plane_create(pp, nn, &s, nullptr, 0), VM_OK);
    vm_mechanism_desc m = desc(VM_MECHANISM_SURFACE_PROBE, s);
    m.unilateral = 1;
    out.push_back({"SurfaceProbePlaneUnilateral", s, m,
                   std::make_shared<SurfaceProbe>(std::make_shared<Plane>(p, n), 0.1, true)});
  }
  {
    const auto letter = vmtest::test_letter(Eigen::Vector3d(0, 0, -0.1));
    vm_mechanism_desc m = desc(VM_MECHANISM_CURVE_GUIDE, c_nurbs_curve(*letter));
    m.length = 0.09;
    out.push_back({"CurveGuide", const_cast<vm_shape*>(m.shape), m,
                   std::make_shared<CurveGuide>(letter, 0.09, z)});
    // a zero normal is +z
    vm_mechanism_desc m0 = desc(VM_MECHANISM_CURVE_GUIDE, c_nurbs_curve(*letter));
    m0.normal[2] = 0.0;
    out.push_back({"CurveGuideZeroNormal", const_cast<vm_shape*>(m0.shape), m0,
                   std::make_shared<CurveGuide>(letter, 0.1, z)});
    const Eigen::Vector3d n = Eigen::Vector3d(0.1, 0.2, 1.0).normalized();
    vm_mechanism_desc h = desc(VM_MECHANISM_HANDLE_PATH, c_nurbs_curve(*letter));
    set3(h.normal, n);
    h.length_scale = 0.12;
    out.push_back({"HandlePath", const_cast<vm_shape*>(h.shape), h,
                   std::make_shared<HandlePath>(letter, n, 0.12)});
    // zero length_scale is 0.1
    vm_mechanism_desc h0 = desc(VM_MECHANISM_HANDLE_PATH, c_nurbs_curve(*letter));
    h0.length_scale = 0.0;
    out.push_back({"HandlePathDefaultScale", const_cast<vm_shape*>(h0.shape), h0,
                   std::make_shared<HandlePath>(letter, z, 0.1)});
  }
  return out;
}

void expect_near_torque(const double* tau, const JointVector& ref, int n, int step) {
  for (int i = 0; i < n; ++i) ASSERT_NEAR(tau[i], ref[i], 1e-12) << "joint " << i << " step " << step;
}

vm_device_desc omni() {
  vm_device_desc d;
  vm_device_desc_init(&d, VM_DEVICE_PHANTOM_OMNI);
  return d;
}

}  // namespace

TEST(CApiShapes, ShapeMechanismsMatchTheCppClassesAfterTheShapeIsDestroyed) {
  const vm_device_desc dev = omni();
  vm_settings settings;
  vm_settings_init(&settings);
  settings.ramp_time_s = 0.02;
  ControllerSettings cs;
  cs.ramp_time_s = 0.02;
  for (ShapeCase& k : shape_cases()) {
    SCOPED_TRACE(k.name);
    vm_controller* c = nullptr;
    char err[256];
    ASSERT_EQ(vm_controller_create(&dev, &k.desc, &settings, &c, err, sizeof err), VM_OK) << err;
    // the controller shares the shape: releasing the handle frees nothing it uses
    vm_shape_destroy(k.shape);
    k.desc.shape = nullptr;
    Controller ref(std::make_shared<PhantomOmni>(), k.cpp, cs);
    ASSERT_EQ(vm_controller_dof(c), 6);
    JointVector q(6), dq(6);
    CycleOutput out;
    vm_diagnostics diag;
    double tau[6];
    double largest = 0.0;
    for (int step = 0; step < 400; ++step) {
      vmtest::joint_state(10 * step, q, dq);  // 4 s of the slow wandering in 400 cycles
      const std::uint32_t s = vm_controller_step(c, q.data(), dq.data(), 6, NAN, tau);
      ref.step(q.data(), dq.data(), out);
      ASSERT_EQ(s, out.status) << step;
      expect_near_torque(tau, out.torque, 6, step);
      vm_controller_diagnostics(c, &diag);
      ASSERT_EQ(diag.mechanism_dof, ref.mechanism().dof());
      for (int i = 0; i < 6; ++i) ASSERT_NEAR(diag.wrench[i], out.wrench[i], 1e-12) << step;
      for (int i = 0; i < ref.mechanism().dof(); ++i) ASSERT_NEAR(diag.theta[i], out.theta[i], 1e-12);
      largest = std::max(largest, out.torque.cwiseAbs().maxCoeff());
    }
    EXPECT_GT(largest, 1e-3);  // the mechanism pushed: the comparison compared forces
    vm_controller_destroy(c);
  }
}

TEST(CApiShapes, ShapeCreatorsNameTheBadParameter) {
  const auto letter = vmtest::test_letter(Eigen::Vector3d::Zero());
  const int n = letter->size();
  std::vector<double> P;
  for (int i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) P.push_back(letter->control_points()(i, a));
  const Eigen::VectorXd w = letter->weights();
  const Eigen::VectorXd knots = letter->knots();  // n + 3 + 1 for the cubic
  char sentinel = 0;  // *out is set to NULL on failure
  vm_shape* s = reinterpret_cast<vm_shape*>(&sentinel);
  char err[256];
  auto starts = [&](const char* prefix) {
    return std::string(err).rfind(prefix, 0) == 0;
  };
  // knots for the cubic given with degree 2: n + 3 values read, four equal first knots
  EXPECT_EQ(vm_nurbs_curve_create(P.data(), w.data(), n, knots.data(), 2, &s, err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("knots: ")) << err;
  EXPECT_EQ(s, nullptr);
  Eigen::VectorXd bad = knots;
  bad[5] = 0.1;  // decreasing
  EXPECT_EQ(vm_nurbs_curve_create(P.data(), w.data(), n, bad.data(), 3, &s, err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("knots: expected non-decreasing")) << err;
  EXPECT_EQ(vm_nurbs_curve_create(P.data(), w.data(), n, knots.data(), 0, &s, err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("degree: ")) << err;
  EXPECT_EQ(vm_nurbs_curve_create(P.data(), w.data(), 3, knots.data(), 3, &s, err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("control_points: ")) << err;
  EXPECT_EQ(vm_nurbs_curve_create(P.data(), w.data(), 0, knots.data(), 3, &s, err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("n: ")) << err;
  EXPECT_EQ(vm_nurbs_curve_create(P.data(), w.data(), n, nullptr, 3, &s, err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("knots: ")) << err;
  Eigen::VectorXd negative = w;
  negative[2] = -1.0;
  EXPECT_EQ(vm_nurbs_curve_create(P.data(), negative.data(), n, knots.data(), 3, &s, err,
                                  sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("weights: ")) << err;
  EXPECT_EQ(vm_nurbs_curve_create(P.data(), w.data(), n, knots.data(), 3, nullptr, err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("out: ")) << err;

  // surface: the test patch's data with a wrong v knot vector, a bad weight
  const auto patch = vmtest::test_patch(Eigen::Vector3d::Zero());
  const int nu = patch->size_u(), nv = patch->size_v();
  std::vector<double> SP, SW;
  for (int i = 0; i < nu * nv; ++i)
    for (int a = 0; a < 3; ++a) SP.push_back(patch->control_points()(i, a));
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) SW.push_back(patch->weights()(i, j));
  const Eigen::VectorXd ku = patch->knots_u(), kv = patch->knots_v();
  EXPECT_EQ(vm_nurbs_surface_create(SP.data(), SW.data(), nu, nv, ku.data(), kv.data(), 3, 3, &s,
                                    err, sizeof err),
            VM_OK)
      << err;
  vm_shape_destroy(s);
  // knots_u for the cubic given with degree_u 2: nu + 3 values read, four equal first knots
  EXPECT_EQ(vm_nurbs_surface_create(SP.data(), SW.data(), nu, nv, ku.data(), kv.data(), 2, 3, &s,
                                    err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("knots_u: ")) << err;
  std::vector<double> SW_bad = SW;
  SW_bad[7] = 0.0;
  EXPECT_EQ(vm_nurbs_surface_create(SP.data(), SW_bad.data(), nu, nv, ku.data(), kv.data(), 3, 3,
                                    &s, err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("weights: ")) << err;
  EXPECT_EQ(vm_nurbs_surface_create(SP.data(), SW.data(), nu, nv, ku.data(), kv.data(), 3, 9, &s,
                                    err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("degree_v: ")) << err;
  EXPECT_EQ(vm_nurbs_surface_create(SP.data(), SW.data(), nu, nv, ku.data(), nullptr, 3, 3, &s,
                                    err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("knots_v: ")) << err;

  // analytic shapes
  const double c[3] = {0, 0, -0.1}, zero[3] = {0, 0, 0}, z[3] = {0, 0, 1};
  EXPECT_EQ(vm_sphere_create(c, -0.04, nullptr, &s, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("radius: ")) << err;
  EXPECT_EQ(vm_sphere_create(c, 0.04, zero, &s, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("axis: ")) << err;
  EXPECT_EQ(vm_sphere_create(nullptr, 0.04, nullptr, &s, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("center: ")) << err;
  EXPECT_EQ(vm_cylinder_create(c, z, -1.0, &s, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("radius: ")) << err;
  EXPECT_EQ(vm_cylinder_create(c, zero, 0.02, &s, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("direction: ")) << err;
  EXPECT_EQ(vm_plane_create(c, zero, &s, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts("normal: ")) << err;
  EXPECT_EQ(s, nullptr);
  EXPECT_EQ(vm_sphere_create(c, 0.04, nullptr, &s, err, sizeof err), VM_OK) << err;
  EXPECT_STREQ(err, "");
  vm_shape_destroy(s);
  vm_shape_destroy(nullptr);
}

TEST(CApiShapes, MechanismOfTheWrongShapeNamesTheField) {
  const vm_device_desc dev = omni();
  vm_shape* curve = c_nurbs_curve(*vmtest::test_letter(Eigen::Vector3d(0, 0, -0.1)));
  vm_shape* surface = c_nurbs_surface(*vmtest::test_patch(Eigen::Vector3d(0, 0, -0.12)));
  vm_controller* c = nullptr;
  char err[256];
  auto create = [&](const vm_mechanism_desc& m) {
    return vm_controller_create(&dev, &m, nullptr, &c, err, sizeof err);
  };
  vm_mechanism_desc m;
  vm_mechanism_desc_init(&m, VM_MECHANISM_SURFACE_PROBE);
  EXPECT_EQ(m.shape, nullptr);
  EXPECT_EQ(create(m), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("mechanism.shape: expected a surface (vm_nurbs_surface_create, "
                                   "vm_sphere_create",
                                   0),
            0u)
      << err;
  EXPECT_NE(std::string(err).find("got NULL"), std::string::npos) << err;
  m.shape = curve;
  EXPECT_EQ(create(m), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("mechanism.shape: expected a surface", 0), 0u) << err;
  EXPECT_NE(std::string(err).find("got a curve"), std::string::npos) << err;
  m.shape = surface;
  m.length = -0.1;
  EXPECT_EQ(create(m), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("mechanism.length: ", 0), 0u) << err;
  m.length = 0.1;
  m.unilateral = 2;
  EXPECT_EQ(create(m), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("mechanism.unilateral: ", 0), 0u) << err;

  for (vm_mechanism_type type : {VM_MECHANISM_CURVE_GUIDE, VM_MECHANISM_HANDLE_PATH}) {
    SCOPED_TRACE(type);
    vm_mechanism_desc_init(&m, type);
    EXPECT_EQ(create(m), VM_ERROR_ARGUMENT);
    EXPECT_EQ(std::string(err), "mechanism.shape: expected a curve (vm_nurbs_curve_create), got NULL");
    m.shape = surface;
    EXPECT_EQ(create(m), VM_ERROR_ARGUMENT);
    EXPECT_NE(std::string(err).find("got a surface"), std::string::npos) << err;
    m.shape = curve;
    m.unilateral = 1;  // only SurfaceProbe among the shape mechanisms lifts off
    EXPECT_EQ(create(m), VM_ERROR_ARGUMENT);
    EXPECT_EQ(std::string(err).rfind("mechanism.unilateral: ", 0), 0u) << err;
    m.unilateral = 0;
    m.normal[0] = 2.0;  // not a unit vector
    EXPECT_EQ(create(m), VM_ERROR_ARGUMENT);
    EXPECT_EQ(std::string(err).rfind("mechanism.normal: ", 0), 0u) << err;
    m.normal[0] = 0.0;
    ASSERT_EQ(create(m), VM_OK) << err;
    vm_controller_destroy(c);
  }
  vm_mechanism_desc_init(&m, VM_MECHANISM_HANDLE_PATH);
  m.shape = curve;
  m.length_scale = -1.0;
  EXPECT_EQ(create(m), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("mechanism.length_scale: ", 0), 0u) << err;
  EXPECT_EQ(c, nullptr);
  vm_shape_destroy(curve);
  vm_shape_destroy(surface);
}

// --- mechanism sets -------------------------------------------------------------------------

TEST(CApiSet, MatchesTheCppMechanismSet) {
  vm_mechanism_set* set = c_make_set(4);
  MechanismSet ref = vmtest::make_set();
  ASSERT_EQ(vm_mechanism_set_dof(set), 6);
  JointVector q(6), dq(6);
  MechanismSetOutput out;
  vm_set_diagnostics diag;
  double tau[6];
  int switches = 0, engaged = 0;
  const int cycles = 3000;
  for (int k = 0; k < cycles; ++k) {
    vmtest::joint_state(3 * k, q, dq);
    const double t = k * 1e-3;
    if (k == cycles / 2) {
      vm_mechanism_set_reset(set);
      ref.reset();
    }
    const std::uint32_t s = vm_mechanism_set_step(set, q.data(), dq.data(), 6, t, tau);
    ref.step(q.data(), dq.data(), out, t);
    ASSERT_EQ(s, out.cycle.status) << k;
    expect_near_torque(tau, out.cycle.torque, 6, k);
    vm_mechanism_set_diagnostics(set, &diag);
    ASSERT_EQ(diag.active, out.active) << k;
    ASSERT_EQ(diag.size, 4);
    ASSERT_EQ(diag.contact, out.contact) << k;
    ASSERT_EQ(diag.switching, out.switching ? 1 : 0) << k;
    for (int i = 0; i < VM_MAX_SET_MEMBERS; ++i) {  // (NaN on both sides on a faulted cycle)
      if (std::isnan(out.distance[i])) {
        ASSERT_TRUE(std::isnan(diag.distance[i])) << k;
      } else {
        ASSERT_NEAR(diag.distance[i], out.distance[i], 1e-12) << k;
      }
    }
    for (int i = 0; i < 6; ++i) {
      ASSERT_NEAR(diag.cycle.torque[i], out.cycle.torque[i], 1e-12);
      ASSERT_NEAR(diag.cycle.wrench[i], out.cycle.wrench[i], 1e-12);
    }
    ASSERT_EQ(diag.cycle.status, out.cycle.status);
    ASSERT_EQ(diag.cycle.mechanism_dof,
              ref.member(out.active >= 0 ? out.active : 0).mechanism().dof());
    switches += out.switching;
    engaged += out.active >= 0;
  }
  EXPECT_GT(engaged, 0);   // the run rendered members, not only zero force
  EXPECT_GT(switches, 0);  // ... and blended from one to another
  vm_mechanism_set_destroy(set);
}

TEST(CApiSet, FullSetBadCallsAndErrors) {
  vm_mechanism_set* set = c_make_set(4);
  vm_mechanism_desc m;
  vm_mechanism_desc_init(&m, VM_MECHANISM_PROBE);
  char err[256];
  EXPECT_EQ(vm_mechanism_set_add(set, &m, nullptr, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_NE(std::string(err).find("full"), std::string::npos) << err;
  // a bad member names its field; the set is unchanged
  vm_mechanism_set* roomy = c_make_set(5);
  vm_mechanism_desc_init(&m, VM_MECHANISM_SURFACE_PROBE);
  EXPECT_EQ(vm_mechanism_set_add(roomy, &m, nullptr, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("mechanism.shape: ", 0), 0u) << err;
  vm_settings s;
  vm_settings_init(&s);
  s.law = 7;
  vm_mechanism_desc_init(&m, VM_MECHANISM_PROBE);
  EXPECT_EQ(vm_mechanism_set_add(roomy, &m, &s, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("settings.law: ", 0), 0u) << err;
  EXPECT_EQ(vm_mechanism_set_add(roomy, &m, nullptr, err, sizeof err), 4) << err;
  EXPECT_EQ(vm_mechanism_set_add(nullptr, &m, nullptr, err, sizeof err), VM_ERROR_ARGUMENT);
  vm_mechanism_set_destroy(roomy);

  // bad n, NULL pointers: n zeros, a fault, nothing written past n
  double q[6] = {0.1, 0.4, 0.3, 0.0, 0.5, 0.0}, dq[6] = {0}, tau[6];
  for (double& x : tau) x = 7.0;
  EXPECT_EQ(vm_mechanism_set_step(set, q, dq, 5, 0.0, tau), VM_STATUS_FAULT_BAD_SIZE);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(tau[i], 0.0);
  EXPECT_EQ(tau[5], 7.0);
  vm_set_diagnostics diag;
  vm_mechanism_set_diagnostics(set, &diag);
  EXPECT_EQ(diag.cycle.status, VM_STATUS_FAULT_BAD_SIZE);
  for (double x : diag.cycle.torque) EXPECT_EQ(x, 0.0);
  for (double& x : tau) x = 7.0;
  EXPECT_NE(vm_mechanism_set_step(set, nullptr, dq, 6, 0.0, tau) & VM_STATUS_FAULT_MASK, 0u);
  for (double x : tau) EXPECT_EQ(x, 0.0);
  for (double& x : tau) x = 7.0;
  EXPECT_NE(vm_mechanism_set_step(nullptr, q, dq, 6, 0.0, tau) & VM_STATUS_FAULT_MASK, 0u);
  for (double x : tau) EXPECT_EQ(x, 0.0);
  // the next good call runs (and ramps in afresh)
  EXPECT_EQ(vm_mechanism_set_step(set, q, dq, 6, 1e-3, tau) & VM_STATUS_FAULT_MASK, 0u);
  vm_mechanism_set_diagnostics(set, &diag);
  EXPECT_LT(diag.cycle.ramp, 0.5);
  vm_mechanism_set_destroy(set);

  // an empty set renders nothing
  const vm_device_desc dev = omni();
  vm_mechanism_set* empty = nullptr;
  ASSERT_EQ(vm_mechanism_set_create(&dev, 2, nullptr, &empty, err, sizeof err), VM_OK) << err;
  for (double& x : tau) x = 7.0;
  EXPECT_EQ(vm_mechanism_set_step(empty, q, dq, 6, 0.0, tau), VM_STATUS_OK);
  for (double x : tau) EXPECT_EQ(x, 0.0);
  vm_mechanism_set_diagnostics(empty, &diag);
  EXPECT_EQ(diag.active, -1);
  EXPECT_EQ(diag.size, 0);
  EXPECT_EQ(diag.cycle.mechanism_dof, 0);
  vm_mechanism_set_destroy(empty);
  vm_mechanism_set_destroy(nullptr);

  // create errors
  char sentinel = 0;  // *out is set to NULL on failure
  vm_mechanism_set* bad = reinterpret_cast<vm_mechanism_set*>(&sentinel);
  EXPECT_EQ(vm_mechanism_set_create(&dev, 0, nullptr, &bad, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("capacity: ", 0), 0u) << err;
  EXPECT_EQ(bad, nullptr);
  EXPECT_EQ(vm_mechanism_set_create(&dev, VM_MAX_SET_MEMBERS + 1, nullptr, &bad, err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("capacity: ", 0), 0u) << err;
  vm_set_settings ss;
  vm_set_settings_init(&ss);
  EXPECT_EQ(ss.snap_distance, MechanismSetSettings().snap_distance);
  ss.release_distance = 0.5 * ss.snap_distance;
  EXPECT_EQ(vm_mechanism_set_create(&dev, 2, &ss, &bad, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("settings.release_distance: ", 0), 0u) << err;
  vm_set_settings_init(&ss);
  ss.force_rate = 0.0;
  EXPECT_EQ(vm_mechanism_set_create(&dev, 2, &ss, &bad, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("settings.force_rate: ", 0), 0u) << err;
  vm_device_desc d2 = dev;
  d2.link1 = -1.0;
  EXPECT_EQ(vm_mechanism_set_create(&d2, 2, nullptr, &bad, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("device.link1: ", 0), 0u) << err;
  EXPECT_EQ(vm_mechanism_set_create(&dev, 2, nullptr, nullptr, err, sizeof err),
            VM_ERROR_ARGUMENT);
  EXPECT_EQ(bad, nullptr);
}
