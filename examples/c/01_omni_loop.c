/* A PHANTOM Omni / Touch held to a circle (the paper's Fig. 4 mechanism) through OpenHaptics:
 * a real HD program. HD's scheduler runs the servo callback at 1 kHz; the callback reads the
 * joint and gimbal angles in a frame, the virtmech driver tick turns them into joint torques
 * (velocity estimate, controller, watchdog, ramp-in, stop), and the torques go back to HD in
 * mN·m. It builds without the OpenHaptics SDK: the HD functions are declared in
 * virtmech/drivers/hd_api.h and libHD is loaded at run time.
 *
 *     01_omni_loop_c [LIBHD] [SECONDS]
 *
 * LIBHD: the HD library's file (default: libHD.so on the loader's path, then the OpenHaptics
 * install folders); the tests run it against the project's stand-in (tests/standin). Start
 * with the stylus away from the circle's plane and the gains low on a new device
 * (docs/devices.md, "Running on a real Touch"). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "virtmech.h"
#include "virtmech/drivers/hd_api.h"
#include "virtmech_driver.h"

typedef struct servo {
  vm_hd_api* hd;
  HHD device;
  vm_driver* driver;
  int n;
  struct timespec start;
} servo;

static double seconds_since(const struct timespec* start) {
  struct timespec now;
  clock_gettime(CLOCK_MONOTONIC, &now);
  return (double)(now.tv_sec - start->tv_sec) + 1e-9 * (double)(now.tv_nsec - start->tv_nsec);
}

/* One servo tick, in HD's scheduler thread: no allocation, no lock, no I/O. */
static HDCallbackCode servo_tick(void* data) {
  servo* s = (servo*)data;
  double q[VM_MAX_DOF] = {0}, tau[VM_MAX_DOF] = {0}, torque_mnm[3];
  HDErrorInfo e;
  s->hd->hdBeginFrame(s->device);
  s->hd->hdGetDoublev(HD_CURRENT_JOINT_ANGLES, q);      /* waist, shoulder, elbow [rad] */
  s->hd->hdGetDoublev(HD_CURRENT_GIMBAL_ANGLES, q + 3); /* yaw, pitch, roll [rad] */
  e = s->hd->hdGetError();
  if (e.errorCode != HD_SUCCESS) vm_driver_device_error(s->driver, e.errorCode);
  vm_driver_tick(s->driver, q, s->n, seconds_since(&s->start), tau);
  for (int i = 0; i < 3; ++i) torque_mnm[i] = 1000.0 * tau[i]; /* N·m -> mN·m */
  s->hd->hdSetDoublev(HD_CURRENT_JOINT_TORQUE, torque_mnm);
  s->hd->hdEndFrame(s->device);
  e = s->hd->hdGetError();
  if (e.errorCode != HD_SUCCESS) vm_driver_device_error(s->driver, e.errorCode);
  return HD_CALLBACK_CONTINUE;
}

/* hdCheckCalibration inside a frame, as OpenHaptics' calibration sample runs it. */
typedef struct calibration {
  vm_hd_api* hd;
  HHD device;
  HDenum status;
} calibration;

static HDCallbackCode check_calibration(void* data) {
  calibration* c = (calibration*)data;
  c->hd->hdBeginFrame(c->device);
  c->status = c->hd->hdCheckCalibration();
  if (c->status == HD_CALIBRATION_NEEDS_UPDATE) {
    c->hd->hdUpdateCalibration(HD_CALIBRATION_AUTO);
    c->status = c->hd->hdCheckCalibration();
  }
  c->hd->hdEndFrame(c->device);
  return HD_CALLBACK_DONE;
}

static int hd_failed(vm_hd_api* hd, const char* call) {
  const HDErrorInfo e = hd->hdGetError();
  if (e.errorCode == HD_SUCCESS) return 0;
  const char* name = vm_hd_error_name(e.errorCode);
  fprintf(stderr, "%s: %s (0x%04X): %s\n", call, name ? name : "HD error", e.errorCode,
          hd->hdGetErrorString(e.errorCode));
  return 1;
}

static void sleep_ms(long ms) {
  struct timespec d = {ms / 1000, (ms % 1000) * 1000000L};
  nanosleep(&d, NULL);
}

int main(int argc, char** argv) {
  const char* library = argc > 1 ? argv[1] : NULL;
  const double duration_s = argc > 2 ? atof(argv[2]) : 1.0;
  char error[1024];
  vm_hd_api hd;
  if (vm_hd_load(library, &hd, error, sizeof error) != 0) {
    fprintf(stderr, "virtmech: %s\n", error);
    return 2;
  }

  /* the controller: the Omni's handle held to a circle in the x-y plane */
  vm_device_desc device;
  vm_device_desc_init(&device, VM_DEVICE_PHANTOM_OMNI);
  vm_mechanism_desc circle;
  vm_mechanism_desc_init(&circle, VM_MECHANISM_PLANAR_ARM);
  circle.point[2] = -0.1; /* pivot [m] */
  circle.length = 0.05;   /* radius [m] */
  vm_settings settings;
  vm_settings_init(&settings);
  settings.watchdog_s = 0.003; /* a tick 3 ms after the last zeroes the force, then it ramps in */
  vm_controller* controller = NULL;
  if (vm_controller_create(&device, &circle, &settings, &controller, error, sizeof error) != VM_OK) {
    fprintf(stderr, "virtmech: %s\n", error);
    return 1;
  }
  vm_driver* driver = NULL;
  if (vm_driver_create(controller, NULL, &driver, error, sizeof error) != VM_OK) {
    fprintf(stderr, "virtmech: %s\n", error);
    return 1;
  }

  /* the device */
  const HHD handle = hd.hdInitDevice(HD_DEFAULT_DEVICE);
  if (hd_failed(&hd, "hdInitDevice") || handle == HD_INVALID_HANDLE) return 1;
  printf("virtmech %s on %s (%s), Omni + PlanarArm\n", vm_version(),
         hd.hdGetString(HD_DEVICE_MODEL_TYPE), hd.path);
  hd.hdStartScheduler();
  if (hd_failed(&hd, "hdStartScheduler")) return 1;
  calibration cal = {&hd, handle, 0};
  hd.hdScheduleSynchronous(check_calibration, &cal, HD_MIN_SCHEDULER_PRIORITY);
  if (cal.status != HD_CALIBRATION_OK) {
    fprintf(stderr, "virtmech: the device needs calibrating: put the stylus in the inkwell\n");
    hd.hdStopScheduler();
    hd.hdDisableDevice(handle);
    return 1;
  }
  servo s = {&hd, handle, driver, vm_controller_dof(controller), {0, 0}};
  clock_gettime(CLOCK_MONOTONIC, &s.start);
  hd.hdEnable(HD_FORCE_OUTPUT);
  const HDSchedulerHandle callback =
      hd.hdScheduleAsynchronous(servo_tick, &s, HD_MAX_SCHEDULER_PRIORITY);
  if (hd_failed(&hd, "hdScheduleAsynchronous")) return 1;

  /* a normal thread: the records, a line every 100 ms */
  printf("%8s %10s %10s %10s %8s %8s\n", "t [s]", "tau0", "tau1", "tau2", "|f| [N]", "ramp");
  vm_driver_record records[256];
  vm_driver_stats stats;
  double next_line = 0.0;
  for (;;) {
    sleep_ms(20);
    size_t got;
    while ((got = vm_driver_read_records(driver, records, 256)) > 0) {
      for (size_t i = 0; i < got; ++i) {
        const vm_driver_record* r = &records[i];
        if (r->t_s < next_line) continue;
        next_line += 0.1;
        const double* f = r->wrench;
        printf("%8.3f %10.5f %10.5f %10.5f %8.4f %8.3f\n", r->t_s, r->command[0], r->command[1],
               r->command[2], sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]), r->ramp);
      }
    }
    vm_driver_statistics(driver, &stats);
    if (stats.stop != VM_DRIVER_RUNNING || seconds_since(&s.start) >= duration_s) break;
  }

  /* stop: zero torque (a tick sends it), the scheduler, the callback, the device */
  vm_driver_request_stop(driver);
  sleep_ms(5);
  hd.hdStopScheduler();
  hd.hdUnschedule(callback);
  hd.hdDisableDevice(handle);
  vm_driver_statistics(driver, &stats);
  printf("%llu ticks at %.1f Hz, %llu late, worst tick %.1f us\n",
         (unsigned long long)stats.ticks, stats.rate_hz, (unsigned long long)stats.late,
         stats.worst_tick_us);
  const int failed = stats.stop == VM_DRIVER_STOP_DEVICE_ERROR;
  if (failed) {
    const char* name = vm_hd_error_name(stats.device_error);
    fprintf(stderr, "virtmech: device error %s (0x%04X): %s\n", name ? name : "HD error",
            stats.device_error, hd.hdGetErrorString(stats.device_error));
  }
  vm_driver_destroy(driver);
  vm_controller_destroy(controller);
  vm_hd_unload(&hd);
  return failed ? 1 : 0;
}
