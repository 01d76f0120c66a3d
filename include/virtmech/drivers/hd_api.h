/* The subset of the OpenHaptics HD API (3D Systems; Touch, Touch X, PHANTOM Omni) that virtmech
 * uses: its types, constant values and function signatures, as the HD library exports them.
 * Nothing of the proprietary SDK is needed to build: the library (libHD.so, installed by
 * "OpenHaptics for Linux") is loaded at run time with vm_hd_load, and its functions are
 * called through the table it fills, e.g. hd.hdBeginFrame(device).
 *
 * Units at this API: joint and gimbal angles rad, position mm, joint and gimbal torque mN·m,
 * force N, stiffness N/mm. docs/devices.md, "Running on a real Touch". */
#ifndef VIRTMECH_DRIVERS_HD_API_H_
#define VIRTMECH_DRIVERS_HD_API_H_

#include <limits.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef unsigned int HDuint;
typedef unsigned char HDboolean;
typedef unsigned long HDulong;
typedef unsigned short HDushort;
typedef int HDint;
typedef double HDdouble;
typedef unsigned int HDerror;
typedef unsigned int HDenum;
typedef const char* HDstring;
typedef unsigned int HHD;

/* An error from the HD error stack (hdGetError). */
typedef struct {
  HDerror errorCode;     /* the HD_ error code; HD_SUCCESS when there is none */
  int internalErrorCode; /* the device's own code */
  HHD hHD;               /* the device current when it occurred */
} HDErrorInfo;

/* Scheduler callbacks return whether they run again next tick. */
typedef unsigned int HDCallbackCode;
typedef HDCallbackCode (*HDSchedulerCallback)(void* user_data);
typedef unsigned long HDSchedulerHandle;
#define HD_CALLBACK_DONE 0
#define HD_CALLBACK_CONTINUE 1
#define HD_MAX_SCHEDULER_PRIORITY USHRT_MAX
#define HD_MIN_SCHEDULER_PRIORITY 0

/* Devices. */
#define HD_DEFAULT_DEVICE NULL
#define HD_INVALID_HANDLE 0xFFFFFFFF

/* Errors. */
#define HD_SUCCESS 0x0000
#define HD_INVALID_ENUM 0x0100
#define HD_INVALID_VALUE 0x0101
#define HD_INVALID_OPERATION 0x0102
#define HD_INVALID_INPUT_TYPE 0x0103
#define HD_BAD_HANDLE 0x0104
#define HD_WARM_MOTORS 0x0200
#define HD_EXCEEDED_MAX_FORCE 0x0201
#define HD_EXCEEDED_MAX_FORCE_IMPULSE 0x0202
#define HD_EXCEEDED_MAX_VELOCITY 0x0203
#define HD_FORCE_ERROR 0x0204
#define HD_DEVICE_FAULT 0x0300
#define HD_DEVICE_ALREADY_INITIATED 0x0301
#define HD_COMM_ERROR 0x0302
#define HD_COMM_CONFIG_ERROR 0x0303
#define HD_TIMER_ERROR 0x0304
#define HD_ILLEGAL_BEGIN 0x0400
#define HD_ILLEGAL_END 0x0401
#define HD_FRAME_ERROR 0x0402
#define HD_INVALID_PRIORITY 0x0500
#define HD_SCHEDULER_FULL 0x0501
#define HD_INVALID_LICENSE 0x0600

/* State (hdGet*). */
#define HD_CURRENT_BUTTONS 0x2000
#define HD_CURRENT_INKWELL_SWITCH 0x2002
#define HD_CURRENT_POSITION 0x2050
#define HD_CURRENT_JOINT_ANGLES 0x2100  /* 3: waist, shoulder, elbow (absolute) [rad] */
#define HD_CURRENT_GIMBAL_ANGLES 0x2150 /* 3: yaw, pitch, roll [rad] */
#define HD_VERSION 0x2500
#define HD_DEVICE_MODEL_TYPE 0x2501
#define HD_DEVICE_DRIVER_VERSION 0x2502
#define HD_DEVICE_VENDOR 0x2503
#define HD_DEVICE_SERIAL_NUMBER 0x2504
#define HD_INPUT_DOF 0x2553
#define HD_OUTPUT_DOF 0x2554
#define HD_CALIBRATION_STYLE 0x2555
#define HD_UPDATE_RATE 0x2600
#define HD_INSTANTANEOUS_UPDATE_RATE 0x2601
#define HD_NOMINAL_MAX_STIFFNESS 0x2602        /* [N/mm] */
#define HD_NOMINAL_MAX_FORCE 0x2603            /* [N] */
#define HD_NOMINAL_MAX_CONTINUOUS_FORCE 0x2604 /* [N] */
#define HD_NOMINAL_MAX_DAMPING 0x2609          /* [N·s/mm] */

/* Commands (hdSet*, inside a frame). */
#define HD_CURRENT_FORCE 0x2700
#define HD_CURRENT_JOINT_TORQUE 0x2703  /* 3 [mN·m] */
#define HD_CURRENT_GIMBAL_TORQUE 0x2704 /* 3 [mN·m], models with gimbal motors only */

/* Capabilities (hdEnable). */
#define HD_FORCE_OUTPUT 0x4000

/* Calibration. */
#define HD_CALIBRATION_OK 0x5000
#define HD_CALIBRATION_NEEDS_UPDATE 0x5001
#define HD_CALIBRATION_NEEDS_MANUAL_INPUT 0x5002
#define HD_CALIBRATION_ENCODER_RESET (1 << 0)
#define HD_CALIBRATION_AUTO (1 << 1)
#define HD_CALIBRATION_INKWELL (1 << 2)

/* Every function virtmech calls: X(return type, name, parameters). */
#define VM_HD_FUNCTIONS(X)                                                                   \
  X(HHD, hdInitDevice, (HDstring name))                                                      \
  X(void, hdDisableDevice, (HHD device))                                                     \
  X(void, hdMakeCurrentDevice, (HHD device))                                                 \
  X(HHD, hdGetCurrentDevice, (void))                                                         \
  X(void, hdBeginFrame, (HHD device))                                                        \
  X(void, hdEndFrame, (HHD device))                                                          \
  X(HDErrorInfo, hdGetError, (void))                                                         \
  X(HDstring, hdGetErrorString, (HDerror code))                                              \
  X(void, hdEnable, (HDenum capability))                                                     \
  X(void, hdDisable, (HDenum capability))                                                    \
  X(HDboolean, hdIsEnabled, (HDenum capability))                                             \
  X(void, hdGetDoublev, (HDenum name, HDdouble * values))                                    \
  X(void, hdGetIntegerv, (HDenum name, HDint * values))                                      \
  X(HDstring, hdGetString, (HDenum name))                                                    \
  X(void, hdSetDoublev, (HDenum name, const HDdouble* values))                               \
  X(HDenum, hdCheckCalibration, (void))                                                      \
  X(void, hdUpdateCalibration, (HDenum style))                                               \
  X(void, hdStartScheduler, (void))                                                          \
  X(void, hdStopScheduler, (void))                                                           \
  X(HDSchedulerHandle, hdScheduleAsynchronous,                                               \
    (HDSchedulerCallback callback, void* user_data, HDushort priority))                      \
  X(void, hdScheduleSynchronous,                                                             \
    (HDSchedulerCallback callback, void* user_data, HDushort priority))                      \
  X(void, hdUnschedule, (HDSchedulerHandle handle))

/* The HD library, loaded: one pointer per function of VM_HD_FUNCTIONS. */
typedef struct vm_hd_api {
#define VM_HD_POINTER(ret, name, params) ret(*name) params;
  VM_HD_FUNCTIONS(VM_HD_POINTER)
#undef VM_HD_POINTER
  void* library;  /* the dlopen handle */
  char path[1024]; /* the library loaded (as given to dlopen) */
} vm_hd_api;

/* Loads the HD library and fills `api`. `path`: the library's file; NULL or "": "libHD.so"
 * through the loader's search path (LD_LIBRARY_PATH, the system's libraries), then the
 * OpenHaptics install folders (/opt/OpenHaptics/Developer/<version>/lib, /opt/OpenHaptics/lib).
 * Returns 0, or -1 with a message in `error` (naming what was tried and what to install). */
int vm_hd_load(const char* path, vm_hd_api* api, char* error, size_t error_size);

/* Unloads a library vm_hd_load loaded (api zeroed); nothing for a zeroed api. */
void vm_hd_unload(vm_hd_api* api);

/* The name of an HD error code ("HD_COMM_ERROR"), or NULL for an unknown code. */
const char* vm_hd_error_name(HDerror code);

#ifdef __cplusplus
}
#endif

#endif /* VIRTMECH_DRIVERS_HD_API_H_ */
