/* A servo loop against the PHANTOM Omni model through the C API: the handle is held to a
 * circle in the x-y plane (the paper's Fig. 4 mechanism). The device is replaced by a
 * synthetic motion; in a real driver, q and dq come from HD_CURRENT_JOINT_ANGLES /
 * HD_CURRENT_GIMBAL_ANGLES (converted to SI) and tau goes to HD_CURRENT_JOINT_TORQUE
 * (in mN·m). */
#include <math.h>
#include <stdio.h>

#include "virtmech.h"

int main(void) {
  vm_device_desc device;
  vm_device_desc_init(&device, VM_DEVICE_PHANTOM_OMNI);
  vm_mechanism_desc circle;
  vm_mechanism_desc_init(&circle, VM_MECHANISM_PLANAR_ARM);
  circle.point[2] = -0.1; /* pivot [m] */
  circle.length = 0.05;   /* radius [m] */

  vm_controller* controller = NULL;
  char error[256];
  if (vm_controller_create(&device, &circle, NULL, &controller, error, sizeof error) != VM_OK) {
    fprintf(stderr, "virtmech: %s\n", error);
    return 1;
  }
  const int n = vm_controller_dof(controller);
  double q[VM_MAX_DOF] = {0}, dq[VM_MAX_DOF] = {0}, tau[VM_MAX_DOF];
  vm_diagnostics diag;
  printf("virtmech %s, Omni + PlanarArm, %d joints\n", vm_version(), n);
  printf("%8s %10s %10s %10s %8s %8s\n", "t [s]", "tau0", "tau1", "tau2", "|f| [N]", "status");
  for (int k = 0; k <= 1000; ++k) { /* 1 s at 1 kHz */
    const double t = k * 1e-3;
    q[0] = 0.2 * sin(2.0 * t);
    q[1] = 0.5 + 0.1 * sin(3.0 * t);
    q[2] = 0.3;
    q[4] = 0.6;
    dq[0] = 0.4 * cos(2.0 * t);
    dq[1] = 0.3 * cos(3.0 * t);
    const uint32_t status = vm_controller_step(controller, q, dq, n, t, tau);
    if (k % 100 == 0) {
      vm_controller_diagnostics(controller, &diag);
      const double f = sqrt(diag.wrench[0] * diag.wrench[0] + diag.wrench[1] * diag.wrench[1] +
                            diag.wrench[2] * diag.wrench[2]);
      printf("%8.3f %10.5f %10.5f %10.5f %8.4f %8u\n", t, tau[0], tau[1], tau[2], f, status);
    }
  }
  vm_controller_destroy(controller);
  return 0;
}
