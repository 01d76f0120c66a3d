/* The subset of the Force Dimension DHD API (omega.3, omega.6, omega.7, sigma.7 and the Novint
 * Falcon) that virtmech uses: the function signatures and constant values the DHD library
 * exports. Nothing of the SDK is needed to build: the library (libdhd.so, from the vendor's
 * SDK) is loaded at run time with vm_dhd_load, and its functions are called through the table
 * it fills, e.g. dhd.dhdGetSystemType(id).
 *
 * Units at this API: SI (m, rad, N, N·m, m/s, rad/s). Every call takes the device's ID last
 * (-1: the default device) and returns < 0 on error, the message then given by
 * dhdErrorGetLastStr(); positive returns (DHD_TIMEGUARD, DHD_MOTOR_SATURATED) are not errors.
 * docs/devices.md, "Running on a Force Dimension device". */
#ifndef VIRTMECH_DRIVERS_DHD_API_H_
#define VIRTMECH_DRIVERS_DHD_API_H_

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Returns that are not errors. */
#define DHD_TIMEGUARD 1       /* the call came sooner than the device's refresh */
#define DHD_MOTOR_SATURATED 2 /* the force asked for was saturated at the motors */

/* dhdGetSystemType's values (the device's model), as CHAI3D's device table defines them. */
#define VM_DHD_OMEGA3 33
#define VM_DHD_OMEGA6_RIGHT 34
#define VM_DHD_OMEGA7_RIGHT 35
#define VM_DHD_OMEGA6_LEFT 36
#define VM_DHD_OMEGA7_LEFT 37
#define VM_DHD_FALCON 60
#define VM_DHD_DELTA3 63
#define VM_DHD_SIGMA7_RIGHT 104
#define VM_DHD_SIGMA7_LEFT 105

/* Every function virtmech calls: X(return type, name, parameters). */
#define VM_DHD_FUNCTIONS(X)                                                                  \
  X(int, dhdOpen, (void))                                                                    \
  X(int, dhdClose, (char id))                                                                \
  X(int, dhdGetSystemType, (char id))                                                        \
  X(int, dhdEnableForce, (unsigned char on, char id))                                        \
  X(int, dhdGetPositionAndOrientationFrame,                                                  \
    (double* px, double* py, double* pz, double matrix[3][3], char id))                      \
  X(int, dhdGetLinearVelocity, (double* vx, double* vy, double* vz, char id))                \
  X(int, dhdGetAngularVelocityRad, (double* wx, double* wy, double* wz, char id))            \
  X(int, dhdSetForceAndTorque,                                                               \
    (double fx, double fy, double fz, double tx, double ty, double tz, char id))             \
  X(int, dhdSetForceAndTorqueAndGripperForce,                                                \
    (double fx, double fy, double fz, double tx, double ty, double tz, double fg, char id))  \
  X(int, dhdGetButton, (int index, char id))                                                 \
  X(int, dhdStop, (char id))                                                                 \
  X(const char*, dhdErrorGetLastStr, (void))

/* The DHD library, loaded: one pointer per function of VM_DHD_FUNCTIONS. */
typedef struct vm_dhd_api {
#define VM_DHD_POINTER(ret, name, params) ret(*name) params;
  VM_DHD_FUNCTIONS(VM_DHD_POINTER)
#undef VM_DHD_POINTER
  void* library;   /* the dlopen handle */
  char path[1024]; /* the library loaded (as given to dlopen) */
} vm_dhd_api;

/* Loads the DHD library and fills `api`. `path`: the library's file; NULL or "": "libdhd.so"
 * through the loader's search path (LD_LIBRARY_PATH, the system's libraries). Returns 0, or
 * -1 with a message in `error` (naming what was tried and what to install). */
int vm_dhd_load(const char* path, vm_dhd_api* api, char* error, size_t error_size);

/* Unloads a library vm_dhd_load loaded (api zeroed); nothing for a zeroed api. */
void vm_dhd_unload(vm_dhd_api* api);

/* The virtmech model name of a dhdGetSystemType value ("omega.6", "sigma.7", "falcon", ...),
 * or NULL for a device virtmech does not model. */
const char* vm_dhd_model_name(int system_type);

/* A name for any dhdGetSystemType value virtmech knows ("delta.3" too), or NULL. */
const char* vm_dhd_system_name(int system_type);

#ifdef __cplusplus
}
#endif

#endif /* VIRTMECH_DRIVERS_DHD_API_H_ */
