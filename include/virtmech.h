/* virtmech C API: a virtual-mechanism controller for a vendor servo callback
 * (OpenHaptics HD scheduler, CHAI3D, or any 1 kHz+ loop).
 *
 * Allocation: only the setup calls allocate: vm_controller_create, the shape creators
 * (vm_nurbs_curve_create, ...), vm_mechanism_set_create and vm_mechanism_set_add; the
 * matching _destroy calls free. The cycle calls vm_controller_step, vm_controller_reset,
 * vm_controller_diagnostics and their vm_mechanism_set_ counterparts never allocate and never
 * block. All units SI (m, rad, N, N·m, s); convert from device-native units (mm, mN·m) at the
 * boundary.
 *
 * Threads: a vm_controller or a vm_mechanism_set belongs to one thread at a time (its calls
 * are not for concurrent use: one per servo thread); shapes (vm_nurbs_curve, ...) are
 * immutable once created and may be used by controllers on any number of threads.
 */
#ifndef VIRTMECH_H_
#define VIRTMECH_H_

#include <stddef.h>
#include <stdint.h>

#include "virtmech/output_table.h"
#include "virtmech/settings_table.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Return codes of every vm_ call that can fail. */
#define VM_OK 0                 /* success */
#define VM_ERROR_ARGUMENT -1    /* a description or argument was invalid (see message) */
#define VM_ERROR_INTERNAL -2    /* unexpected failure (out of memory) */

/* Status bits returned by vm_controller_step and vm_mechanism_set_step (same as
 * virtmech::status). */
#define VM_STATUS_OK 0u
#define VM_STATUS_RAMPING (1u << 0)
#define VM_STATUS_FORCE_CLAMPED (1u << 1)
#define VM_STATUS_TORQUE_CLAMPED (1u << 2)
#define VM_STATUS_NOT_CONVERGED (1u << 3)
#define VM_STATUS_WATCHDOG (1u << 4)
#define VM_STATUS_PASSIVITY (1u << 5) /* the energy tank held back the range term */
#define VM_STATUS_SWITCHING (1u << 6) /* a mechanism set blends between two members */
#define VM_STATUS_FAULT_NONFINITE_INPUT (1u << 8)
#define VM_STATUS_FAULT_NONFINITE_OUTPUT (1u << 9)
#define VM_STATUS_FAULT_BAD_SIZE (1u << 10)
#define VM_STATUS_FAULT_OUT_OF_RANGE (1u << 11) /* q beyond the joint range + margin */
#define VM_STATUS_FAULT_IMPLAUSIBLE_VELOCITY (1u << 12) /* dq beyond the device's speeds + margin */
#define VM_STATUS_FAULT_MASK 0xFF00u

/* Largest number of joints of a device or mechanism. */
#define VM_MAX_DOF 8

/* Largest capacity of a mechanism set (vm_mechanism_set_create). */
#define VM_MAX_SET_MEMBERS 16

/* Device models (the `type` of a vm_device_desc: an int, checked before it is used). */
typedef enum vm_device_type {
  VM_DEVICE_PHANTOM_OMNI = 0, /* PHANTOM Omni / Geomagic Touch, default parameters */
  VM_DEVICE_PLANAR3R = 1,     /* the paper's Fig. 8 planar robot, distal joint passive */
  VM_DEVICE_SERIAL = 2        /* a serial chain with any actuation mask */
} vm_device_type;

/* Virtual mechanisms (the `type` of a vm_mechanism_desc: an int, checked before it is used). */
typedef enum vm_mechanism_type {
  VM_MECHANISM_PLANAR_ARM = 0,  /* point = pivot, normal, length, direction = zero_direction
                                   (zero = automatic) */
  VM_MECHANISM_PROBE = 1,       /* point = plane point, normal = plane normal, length */
  VM_MECHANISM_POINT_PIVOT = 2, /* point, normal, length */
  VM_MECHANISM_LINE_GUIDE = 3,  /* point, direction, length, normal */
  VM_MECHANISM_SERIAL = 4,      /* a serial chain */
  VM_MECHANISM_SURFACE_PROBE = 5, /* shape = a surface, length, unilateral: the probe's tip
                                     held on the surface (stylus of the given length) */
  VM_MECHANISM_CURVE_GUIDE = 6,   /* shape = a curve, length, normal (unit; zero = +z): the
                                     probe's tip held on the curve, the hand on the normal's
                                     side */
  VM_MECHANISM_HANDLE_PATH = 7    /* shape = a curve, normal (unit; zero = +z), length_scale
                                     (0 = 0.1 m): the handle itself held on the curve, its
                                     orientation free */
} vm_mechanism_type;

/* A curve or surface for the shape mechanisms (VM_MECHANISM_SURFACE_PROBE, _CURVE_GUIDE,
 * _HANDLE_PATH); docs/geometry.md. Opaque; immutable once created. A controller or set
 * member built from a shape shares it: the shape may be destroyed right after
 * vm_controller_create / vm_mechanism_set_add, the mechanism keeps its own reference. */
typedef struct vm_shape vm_shape;

/* One joint of a serial chain: type 0 revolute, 1 prismatic; axis in the joint frame;
 * origin = pose of the joint frame in the previous frame at zero, as a row-major 4x4. */
typedef struct vm_joint {
  int type;
  double axis[3];
  double origin[16];
  double lower; /* [rad or m]; use -HUGE_VAL for none */
  double upper; /* [rad or m]; use HUGE_VAL for none */
} vm_joint;

/* A serial chain: base and handle poses as row-major 4x4 transforms. */
typedef struct vm_chain {
  int dof;
  vm_joint joints[VM_MAX_DOF];
  double base[16];
  double handle[16];
} vm_chain;

/* Device description; vm_device_desc_init fills every field with the type's defaults.
 * VM_DEVICE_PHANTOM_OMNI: link1, link2 (l1, l2), torque_limit[0..2] (motors), max_force,
 *   gimbal_offset, gimbal_sign (driver gimbal angles g map to virtmech's as
 *   sign * (g - offset); docs/devices.md), stiffness, damping.
 * VM_DEVICE_PLANAR3R: link1, link2, base, torque_limit[0], max_force.
 * VM_DEVICE_SERIAL: chain, actuated, torque_limit (<= 0: none), max_force, max_torque
 *   (<= 0: none), stiffness, damping, name. */
typedef struct vm_device_desc {
  int type;                          /* a vm_device_type */
  double link1, link2;               /* [m] (Omni, Planar3R) */
  double base[16];                   /* row-major 4x4 (Planar3R) */
  vm_chain chain;                    /* (serial) */
  int actuated[VM_MAX_DOF];          /* 1 = motor-driven (serial) */
  double torque_limit[VM_MAX_DOF];   /* [N·m or N] */
  double max_force;                  /* [N] */
  double max_torque;                 /* [N·m] (serial) */
  double stiffness;                  /* default translational Kp [N/m] (Omni, serial) */
  double damping;                    /* default translational Kv [N·s/m] (Omni, serial) */
  double gimbal_offset[3];           /* [rad] (Omni) */
  double gimbal_sign[3];             /* +1 or -1 (Omni) */
  char name[64];                     /* (serial) NUL-terminated */
} vm_device_desc;

/* Mechanism description (see vm_mechanism_type for which fields each uses). */
typedef struct vm_mechanism_desc {
  int type;            /* a vm_mechanism_type */
  double point[3];
  double normal[3];
  double direction[3]; /* zero direction (PlanarArm), line direction (LineGuide),
                          tangent (Probe, PointPivot; zero = automatic) */
  double length;       /* [m] */
  int unilateral;      /* 1: the tip may lift off toward +normal (Probe, PointPivot,
                          LineGuide; SurfaceProbe: off the surface's normal side): the
                          surface pushes but never pulls */
  vm_chain chain;      /* (serial) */
  double length_scale; /* [m] (serial, HandlePath: 0 = 0.1) */
  const vm_shape* shape; /* (SurfaceProbe: a surface; CurveGuide, HandlePath: a curve);
                            NULL by vm_mechanism_desc_init. Not kept past the create call. */
} vm_mechanism_desc;

/* The values of vm_settings' enumerations (VM_CONTROL_LAWS, VM_ERROR_VELOCITIES and
 * VM_PASSIVITIES in virtmech/settings_table.h say what each means). */
#define VM_C_LAW(cpp, c, value, name, doc) VM_LAW_##c = value,
#define VM_C_ERROR_VELOCITY(cpp, c, value, name, doc) VM_ERROR_VELOCITY_##c = value,
#define VM_C_PASSIVITY(cpp, c, value, name, doc) VM_PASSIVITY_##c = value,
typedef enum vm_law { VM_CONTROL_LAWS(VM_C_LAW) } vm_law;
typedef enum vm_error_velocity { VM_ERROR_VELOCITIES(VM_C_ERROR_VELOCITY) } vm_error_velocity;
typedef enum vm_passivity { VM_PASSIVITIES(VM_C_PASSIVITY) } vm_passivity;
#undef VM_C_LAW
#undef VM_C_ERROR_VELOCITY
#undef VM_C_PASSIVITY

/* Controller settings, one member per row of VM_CONTROLLER_SETTINGS (virtmech/settings_table.h:
 * each row's unit, default, range and meaning): for a 6-vector row NAME, has_NAME (0 keeps the
 * default, derived from the device and the mechanism) and NAME[6]; a number row a double; an
 * integer row an int; an enumeration row an int (law: VM_LAW_*, error_velocity:
 * VM_ERROR_VELOCITY_*, passivity: VM_PASSIVITY_*), checked as an integer before it is used.
 * vm_settings_init fills the defaults. */
typedef struct vm_settings {
#define VM_C_VEC6(name, unit, doc) int has_##name; double name[6];
#define VM_C_REAL(name, value, min, max, flags, unit, doc) double name;
#define VM_C_INT(name, value, min, max, unit, doc) int name;
#define VM_C_ENUM(name, Type, value, doc) int name;
  VM_CONTROLLER_SETTINGS(VM_C_VEC6, VM_C_REAL, VM_C_INT, VM_C_ENUM)
#undef VM_C_VEC6
#undef VM_C_INT
#undef VM_C_ENUM
} vm_settings;

/* Diagnostics of the last cycle: the dimensions, then one member per row of VM_CYCLE_OUTPUT
 * (virtmech/output_table.h: each field's meaning); joint values fill VM_MAX_DOF entries,
 * zero beyond the dimension, and poses are row-major 4x4. */
typedef struct vm_diagnostics {
  int device_dof, mechanism_dof;
#define VM_D_JOINTS(name, doc) double name[VM_MAX_DOF];
#define VM_D_VEC6(name, doc) double name[6];
#define VM_D_POSE(name, doc) double name[16];
#define VM_D_LOCKS(name, of, doc) uint32_t name;
#define VM_D_INT(name, doc) int name;
#define VM_D_REAL(name, value, doc) double name;
#define VM_D_BITS(name, doc) uint32_t name;
  VM_CYCLE_OUTPUT(VM_D_JOINTS, VM_D_VEC6, VM_D_POSE, VM_D_LOCKS, VM_D_INT, VM_D_REAL, VM_D_BITS)
#undef VM_D_JOINTS
#undef VM_D_VEC6
#undef VM_D_POSE
#undef VM_D_LOCKS
#undef VM_D_INT
#undef VM_D_REAL
#undef VM_D_BITS
} vm_diagnostics;

typedef struct vm_controller vm_controller;

/* Settings of a mechanism set, one double per row of VM_SET_SETTINGS
 * (virtmech/settings_table.h); vm_set_settings_init fills the defaults. */
typedef struct vm_set_settings {
  VM_SET_SETTINGS(VM_C_REAL)
} vm_set_settings;
#undef VM_C_REAL

/* Diagnostics of the last cycle of a mechanism set. */
typedef struct vm_set_diagnostics {
  vm_diagnostics cycle; /* the rendered member's cycle, torque and wrench the set's output
                           (while switching, the blend); with no member engaged member 0's
                           cycle with zero force (mechanism_dof: that member's) */
  int active;           /* the member rendered, -1 for none */
  int size;             /* members in the set */
  double distance[VM_MAX_SET_MEMBERS]; /* each member's distance from the handle [m]; a
                           unilateral member's tip height, 0 in contact; 0 past size;
                           NaN on a faulted cycle, which engages no member */
  uint32_t contact;     /* bit i: member i is unilateral and in contact */
  int switching;        /* 1: the output is moving from one member's force to another's */
} vm_set_diagnostics;

/* Several mechanisms on one device, at most one rendered per cycle: a member engages when
 * the handle comes within snap_distance of it and lets go beyond release_distance; switching
 * members moves the force at no more than the set rates (docs/theory.md, section 7). */
typedef struct vm_mechanism_set vm_mechanism_set;

/* Fills a device description with defaults for the given type (a vm_device_type; another
 * value leaves the type-specific fields zero, and vm_controller_create then refuses it).
 * Does not allocate. */
void vm_device_desc_init(vm_device_desc* desc, int type);
/* Fills a mechanism description with defaults for the given type (a vm_mechanism_type).
 * Does not allocate. */
void vm_mechanism_desc_init(vm_mechanism_desc* desc, int type);
/* Fills settings with the defaults. Does not allocate. */
void vm_settings_init(vm_settings* settings);

/* Creates a controller (the only call that allocates). settings may be NULL. On failure
 * returns VM_ERROR_ARGUMENT and writes a message naming the bad field into error
 * (NUL-terminated, truncated to error_size; error may be NULL). */
int vm_controller_create(const vm_device_desc* device, const vm_mechanism_desc* mechanism,
                         const vm_settings* settings, vm_controller** out, char* error,
                         size_t error_size);
/* Frees a controller (NULL is allowed). */
void vm_controller_destroy(vm_controller* controller);
/* Number of device joints: the length of q, dq and tau. Does not allocate. */
int vm_controller_dof(const vm_controller* controller);
/* One servo cycle: q, dq in (device joints, n each), tau out (n entries); returns status
 * bits. n must be vm_controller_dof(controller). t_s is the cycle's time stamp [s] for the
 * watchdog, or NAN. Never allocates, never fails: a fault status comes with tau = 0 (also
 * for a NULL controller, NULL q or dq, or a wrong n; tau gets n zeros). */
uint32_t vm_controller_step(vm_controller* controller, const double* q, const double* dq, int n,
                            double t_s, double* tau);
/* Restarts placements and the ramp-in. Does not allocate. */
void vm_controller_reset(vm_controller* controller);
/* Copies the diagnostics of the last cycle. Does not allocate. */
void vm_controller_diagnostics(const vm_controller* controller, vm_diagnostics* out);

/* Shapes. Each creator validates its data, builds the shape and returns VM_OK; on failure
 * VM_ERROR_ARGUMENT (VM_ERROR_INTERNAL: out of memory) with *out = NULL and a message naming
 * the bad parameter in error (NUL-terminated, truncated to error_size; error may be NULL).
 * The data are copied: the arrays may be freed after the call. */

/* A NURBS curve: control_points n x 3 row-major [m], weights n (> 0), knots n + degree + 1
 * non-decreasing values (clamped or not; multiplicity at most degree + 1), 1 <= degree <= 7,
 * n >= degree + 1. The knot count follows from n and degree: the array must hold that many. */
int vm_nurbs_curve_create(const double* control_points, const double* weights, int n,
                          const double* knots, int degree, vm_shape** out, char* error,
                          size_t error_size);
/* A tensor-product NURBS surface: control_points nu*nv x 3 row-major, row i*nv + j the point
 * P_ij [m]; weights nu*nv (> 0), row-major (entry i*nv + j weighs P_ij); knots_u nu +
 * degree_u + 1 values, knots_v nv + degree_v + 1 (as a curve's); 1 <= degree_u, degree_v
 * <= 7. */
int vm_nurbs_surface_create(const double* control_points, const double* weights, int nu,
                            int nv, const double* knots_u, const double* knots_v, int degree_u,
                            int degree_v, vm_shape** out, char* error, size_t error_size);
/* A sphere: center [m], radius > 0 [m], axis (non-zero; NULL: +z) toward the pole of the
 * parametrisation (keep the poles away from where the probe works; docs/geometry.md). */
int vm_sphere_create(const double center[3], double radius, const double axis[3],
                     vm_shape** out, char* error, size_t error_size);
/* An infinite circular cylinder: a point on its axis [m], the axis direction (non-zero),
 * radius > 0 [m]. */
int vm_cylinder_create(const double point[3], const double direction[3], double radius,
                       vm_shape** out, char* error, size_t error_size);
/* An infinite plane through point [m] with the given normal (non-zero). */
int vm_plane_create(const double point[3], const double normal[3], vm_shape** out, char* error,
                    size_t error_size);
/* Releases a shape (NULL is allowed). Mechanisms built from it keep their own reference. */
void vm_shape_destroy(vm_shape* shape);

/* Mechanism sets. */

/* Fills set settings with the defaults. Does not allocate. */
void vm_set_settings_init(vm_set_settings* settings);
/* Creates an empty set of at most capacity members (1 to VM_MAX_SET_MEMBERS) on the device;
 * settings may be NULL (defaults). Allocates; returns VM_OK, or VM_ERROR_ARGUMENT with
 * *out = NULL and a message naming the bad field (as vm_controller_create). */
int vm_mechanism_set_create(const vm_device_desc* device, int capacity,
                            const vm_set_settings* settings, vm_mechanism_set** out,
                            char* error, size_t error_size);
/* Adds a member: a controller of the mechanism on the set's device with the given settings
 * (NULL: defaults). Allocates (not for the servo loop). Returns the member's index (>= 0),
 * or VM_ERROR_ARGUMENT (a bad description, the set full) / VM_ERROR_INTERNAL with a
 * message in error. */
int vm_mechanism_set_add(vm_mechanism_set* set, const vm_mechanism_desc* mechanism,
                         const vm_settings* settings, char* error, size_t error_size);
/* Frees a set and its members (NULL is allowed). */
void vm_mechanism_set_destroy(vm_mechanism_set* set);
/* Number of device joints: the length of q, dq and tau. Does not allocate. */
int vm_mechanism_set_dof(const vm_mechanism_set* set);
/* One servo cycle of every member; the set renders at most one (tau, n entries; zero with no
 * member added). Returns status bits (VM_STATUS_SWITCHING while blending). Same contract as
 * vm_controller_step: never allocates, never fails; a fault status comes with tau = 0 (also
 * for a NULL set, NULL q or dq, or a wrong n: tau gets n zeros, the status
 * VM_STATUS_FAULT_BAD_SIZE, and every member ramps in again once the calls are right). */
uint32_t vm_mechanism_set_step(vm_mechanism_set* set, const double* q, const double* dq, int n,
                               double t_s, double* tau);
/* Restarts every member and the selection. Does not allocate. */
void vm_mechanism_set_reset(vm_mechanism_set* set);
/* Copies the diagnostics of the last cycle. Does not allocate. */
void vm_mechanism_set_diagnostics(const vm_mechanism_set* set, vm_set_diagnostics* out);

/* The library's version, e.g. "0.1.0". */
const char* vm_version(void);

#ifdef __cplusplus
}
#endif

#endif /* VIRTMECH_H_ */
