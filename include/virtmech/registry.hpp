// The kinds of mechanisms, devices, curves and surfaces, each one entry of a registry: its
// parameters (name, kind, default, range, unit, meaning), a factory from them, describe()
// (its parameters back, for run information), and for a mechanism its distance measure, the
// directions it constrains and how it is drawn. A kind lives in its own file next to its
// class (src/kinds/); adding one is that file and one line of the list of built-in kinds
// (src/kinds/builtin.cpp), or a plugin: a shared library whose registration function
// receives the host's registry (VIRTMECH_PLUGIN below, load_plugin()).
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <string>
#include <typeindex>
#include <vector>

#include "virtmech/controller.hpp"
#include "virtmech/device.hpp"
#include "virtmech/mechanism.hpp"
#include "virtmech/params.hpp"
#include "virtmech/version.hpp"

namespace virtmech {

/// How far the handle is from a mechanism [m] (the simulation's log columns dist,
/// dist_signed, dist_normal, dist_across; docs/scenarios.md, "Distances and metrics").
struct Distances {
  double dist = 0.0;         //!< from where the mechanism lets its point be (>= 0)
  double dist_signed = 0.0;  //!< signed; negative on the side the mechanism pushes from
  double dist_normal = 0.0;  //!< the part along the mechanism's normal
  double dist_across = 0.0;  //!< the rest
};

/// A direction a mechanism holds its point in, with the name reports give it.
struct NamedDirection {
  std::string name;
  Eigen::Vector3d direction;  //!< unit, world axes
};

/// How a mechanism is drawn: polylines, points and triangle meshes in world axes [m].
struct Sketch {
  struct Mesh {
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> faces;
  };
  std::vector<std::vector<Eigen::Vector3d>> lines;
  std::vector<Eigen::Vector3d> points;
  std::vector<Mesh> meshes;
};

/// One kind of Base (a Mechanism, a Device, a Curve or a Surface).
template <class Base>
struct Kind {
  std::string name;  //!< the "type" users write ("PlanarArm")
  std::string doc;
  std::vector<ParamSpec> params;
  /// The C++ class the factory makes (describe() finds an object's kind by it).
  std::type_index type = typeid(void);
  /// An object from parameters already completed against `params` (complete()).
  std::function<std::shared_ptr<const Base>(const Params&)> make;
  /// The object's parameters ("type" first): make(describe(x)) rebuilds x.
  std::function<Params(const Base&)> describe;
};

using DeviceKind = Kind<Device>;
using CurveKind = Kind<Curve>;
using SurfaceKind = Kind<Surface>;

/// A kind of mechanism, with what the simulation, the quality measures and the viewer ask
/// of it. Empty functions take the generic fallbacks (distance(), constrained_directions(),
/// sketch() below).
struct MechanismKind : Kind<Mechanism> {
  std::string point = "handle";  //!< the point measured: "handle" or "tip"
  std::string target;            //!< what it is measured from ("the circle")
  std::string signed_label;      //!< the signed distance's name in figures
  std::string negative;          //!< what a negative signed distance means
  /// The handle at position p with its stylus (the handle frame's +z, unit) along s: its
  /// distances from the mechanism (the tip is p + length s for a probe).
  std::function<Distances(const Mechanism&, const Eigen::Vector3d& p, const Eigen::Vector3d& s)>
      distance;
  /// The directions the mechanism holds its point in, with the point (the handle or tip,
  /// as `point` says) at rest at `at`.
  std::function<std::vector<NamedDirection>(const Mechanism&, const Eigen::Vector3d& at)>
      constrained;
  std::function<Sketch(const Mechanism&)> sketch;
};

/// The kinds known to a process. Plugins receive the host's (virtual calls run the host's
/// code whatever a plugin was linked with).
class Registry {
 public:
  virtual ~Registry() = default;
  /// Adds a kind; std::invalid_argument for a name already taken or an incomplete kind.
  virtual void add(MechanismKind kind) = 0;
  virtual void add(DeviceKind kind) = 0;
  virtual void add(CurveKind kind) = 0;
  virtual void add(SurfaceKind kind) = 0;
  /// The kind of that name, or nullptr.
  virtual const MechanismKind* mechanism(const std::string& name) const = 0;
  virtual const DeviceKind* device(const std::string& name) const = 0;
  virtual const CurveKind* curve(const std::string& name) const = 0;
  virtual const SurfaceKind* surface(const std::string& name) const = 0;
  /// Every kind, in the order added.
  virtual std::vector<const MechanismKind*> mechanisms() const = 0;
  virtual std::vector<const DeviceKind*> devices() const = 0;
  virtual std::vector<const CurveKind*> curves() const = 0;
  virtual std::vector<const SurfaceKind*> surfaces() const = 0;
};

/// The process's registry, with the built-in kinds (made on first use; thread-safe).
Registry& registry();

/// An object from its parameters (`params.type()` names the kind): the parameters checked
/// and completed against the kind's (complete(); messages name `where` + the parameter,
/// "mechanism.length: ..."), then its factory. std::invalid_argument on any mistake.
std::shared_ptr<const Mechanism> make_mechanism(const Params& params,
                                                const std::string& where = "mechanism");
std::shared_ptr<const Device> make_device(const Params& params,
                                          const std::string& where = "device");
std::shared_ptr<const Curve> make_curve(const Params& params, const std::string& where = "curve");
std::shared_ptr<const Surface> make_surface(const Params& params,
                                            const std::string& where = "surface");

/// An object's parameters ("type" first) from its kind; std::invalid_argument for an object
/// of no registered kind.
Params describe(const Mechanism& mechanism);
Params describe(const Device& device);
Params describe(const Curve& curve);
Params describe(const Surface& surface);
/// A controller's resolved settings (every default filled in), for run information.
Params describe(const ControllerModel& model);

/// The kind of a mechanism (its class), or nullptr for an unregistered class.
const MechanismKind* kind_of(const Mechanism& mechanism);

/// The distances of the handle at p, stylus s, from the mechanism, its kind's measure (the
/// one definition: the simulation's log and the figures use it); a kind without one: the
/// size of `position_error` (the nearest placement's, e[0:3]) in dist and dist_signed, NaN
/// in the two parts.
Distances distance(const Mechanism& mechanism, const Eigen::Vector3d& p,
                   const Eigen::Vector3d& s, const Eigen::Vector3d& position_error);
/// distance() for n handles at once (one lookup of the kind): p, s, position_error row-major
/// (n, 3); out row-major (n, 4) [dist, dist_signed, dist_normal, dist_across].
void distances(const Mechanism& mechanism, long n, const double* p, const double* s,
               const double* position_error, double* out);
/// Its kind's constrained directions at `at` (none for a kind that has not said).
std::vector<NamedDirection> constrained_directions(const Mechanism& mechanism,
                                                   const Eigen::Vector3d& at);
/// Its kind's sketch, or the handle's path as joint 0 sweeps its range (the others at home)
/// for a kind without one.
Sketch sketch(const Mechanism& mechanism);

// ---- plugins ------------------------------------------------------------------------------

/// What a plugin and its host must share to exchange kinds: this library's version, the
/// registry's interface, Eigen's version and alignment, the joint capacity and the C++
/// library's ABI. A plugin compiled against other headers is refused.
#define VIRTMECH_REGISTRY_ABI 1
#define VIRTMECH_STR_(x) #x
#define VIRTMECH_STR(x) VIRTMECH_STR_(x)
#if defined(_LIBCPP_VERSION)
#define VIRTMECH_CXX_ABI "libc++ " VIRTMECH_STR(_LIBCPP_ABI_VERSION)
#elif defined(__GLIBCXX__)
#define VIRTMECH_CXX_ABI \
  "libstdc++ cxx11-abi " VIRTMECH_STR(_GLIBCXX_USE_CXX11_ABI) " gxx-abi " VIRTMECH_STR(__GXX_ABI_VERSION)
#else
#define VIRTMECH_CXX_ABI "unknown C++ library"
#endif
#define VIRTMECH_ABI_TAG                                                                       \
  "virtmech " VIRTMECH_VERSION_STRING "; registry " VIRTMECH_STR(VIRTMECH_REGISTRY_ABI)        \
  "; eigen " VIRTMECH_STR(EIGEN_WORLD_VERSION) "." VIRTMECH_STR(EIGEN_MAJOR_VERSION) "."       \
  VIRTMECH_STR(EIGEN_MINOR_VERSION) " align " VIRTMECH_STR(EIGEN_MAX_STATIC_ALIGN_BYTES)       \
  "; max dof 8; " VIRTMECH_CXX_ABI
static_assert(kMaxDof == 8, "VIRTMECH_ABI_TAG states the joint capacity");

#if defined(_WIN32)
#define VIRTMECH_PLUGIN_EXPORT __declspec(dllexport)
#else
#define VIRTMECH_PLUGIN_EXPORT __attribute__((visibility("default")))
#endif

/// Declares a plugin's entry points: `function(virtmech::Registry&)` adds its kinds. Put it
/// once in the plugin's sources (examples/cpp/02_custom_mechanism.cpp).
#define VIRTMECH_PLUGIN(function)                                                          \
  extern "C" VIRTMECH_PLUGIN_EXPORT const char* virtmech_plugin_abi() {                    \
    return VIRTMECH_ABI_TAG;                                                               \
  }                                                                                        \
  extern "C" VIRTMECH_PLUGIN_EXPORT void virtmech_plugin_register(::virtmech::Registry* r) { \
    function(*r);                                                                          \
  }

/// Loads a plugin (a shared library with VIRTMECH_PLUGIN) into the process's registry:
/// checks its ABI tag against this library's, then runs its registration. A path already
/// loaded is not loaded again. std::invalid_argument naming the path for a file that cannot
/// be loaded, that is no plugin, or that was built against other headers. Not real-time.
void load_plugin(const std::string& path);

}  // namespace virtmech
