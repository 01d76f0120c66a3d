/* A servo loop against the PHANTOM Omni model through the C API: the probe's tip is held on
 * a small NURBS dome (a rational biquadratic patch 8 cm x 8 cm, its top 1.5 cm above the
 * rim) lying on a table, the hand above it (the paper's Fig. 3 mechanism on a curved surface:
 * VM_MECHANISM_SURFACE_PROBE). The device is replaced by a synthetic motion; in a real driver,
 * q and dq come from HD_CURRENT_JOINT_ANGLES / HD_CURRENT_GIMBAL_ANGLES (converted to SI)
 * and tau goes to HD_CURRENT_JOINT_TORQUE (in mN·m). Everything that allocates (the shape,
 * the controller) happens before the loop; the shape is released as soon as the controller
 * holds it. */
#include <math.h>
#include <stdio.h>

#include "virtmech.h"

int main(void) {
  /* the dome: 3 x 3 control points P_ij, row i * 3 + j, in the Omni's base frame (y up) */
  enum { NU = 3, NV = 3, DEGREE = 2 };
  const double rim_y = -0.035, top = 0.015, half = 0.04; /* [m] */
  double points[NU * NV * 3], weights[NU * NV];
  for (int i = 0; i < NU; ++i) {
    for (int j = 0; j < NV; ++j) {
      double* p = &points[3 * (i * NV + j)];
      p[0] = -half + half * i;                                  /* x */
      p[1] = rim_y + ((i == 1 && j == 1) ? 2.0 * top : 0.0);    /* the middle point lifted */
      p[2] = -half + half * j - 0.03;                           /* z */
      weights[i * NV + j] = (i == 1 || j == 1) ? 0.9 : 1.0;
    }
  }
  const double knots[NU + DEGREE + 1] = {0, 0, 0, 1, 1, 1}; /* the same in u and v */

  char error[256];
  vm_shape* dome = NULL;
  if (vm_nurbs_surface_create(points, weights, NU, NV, knots, knots, DEGREE, DEGREE, &dome,
                              error, sizeof error) != VM_OK) {
    fprintf(stderr, "virtmech: %s\n", error);
    return 1;
  }

  vm_device_desc device;
  vm_device_desc_init(&device, VM_DEVICE_PHANTOM_OMNI);
  vm_mechanism_desc probe;
  vm_mechanism_desc_init(&probe, VM_MECHANISM_SURFACE_PROBE);
  probe.shape = dome;
  probe.length = 0.1; /* stylus [m] */
  probe.unilateral = 1; /* the dome pushes, never pulls: the tip may lift off */
  vm_settings settings;
  vm_settings_init(&settings);
  settings.ramp_time_s = 0.1;

  vm_controller* controller = NULL;
  const int rc = vm_controller_create(&device, &probe, &settings, &controller, error, sizeof error);
  vm_shape_destroy(dome); /* the controller keeps its own reference */
  if (rc != VM_OK) {
    fprintf(stderr, "virtmech: %s\n", error);
    return 1;
  }

  const int n = vm_controller_dof(controller);
  double q[VM_MAX_DOF] = {0}, dq[VM_MAX_DOF] = {0}, tau[VM_MAX_DOF];
  vm_diagnostics diag;
  int faults = 0;
  printf("virtmech %s, Omni + SurfaceProbe on a NURBS dome, %d joints\n", vm_version(), n);
  printf("%8s %10s %10s %10s %8s %8s %8s\n", "t [s]", "tau0", "tau1", "tau2", "|f| [N]",
         "lift [m]", "status");
  for (int k = 0; k <= 2000; ++k) { /* 2 s at 1 kHz */
    const double t = k * 1e-3;
    q[0] = 0.25 * sin(1.5 * t);
    q[1] = 0.3 + 0.1 * sin(2.0 * t);
    q[2] = 0.35;
    q[4] = 0.8;
    dq[0] = 0.375 * cos(1.5 * t);
    dq[1] = 0.2 * cos(2.0 * t);
    const uint32_t status = vm_controller_step(controller, q, dq, n, t, tau);
    if (status & VM_STATUS_FAULT_MASK) ++faults; /* tau is zero then */
    if (k % 200 == 0) {
      vm_controller_diagnostics(controller, &diag);
      const double f = sqrt(diag.wrench[0] * diag.wrench[0] + diag.wrench[1] * diag.wrench[1] +
                            diag.wrench[2] * diag.wrench[2]);
      /* theta = [u, v, h, wrist...]: h the tip's height above the dome (unpowered placement) */
      printf("%8.3f %10.5f %10.5f %10.5f %8.4f %8.4f %8u\n", t, tau[0], tau[1], tau[2], f,
             diag.theta_star[2], status);
    }
  }
  vm_controller_destroy(controller);
  if (faults) fprintf(stderr, "virtmech: %d faulted cycles\n", faults);
  return faults ? 1 : 0;
}
