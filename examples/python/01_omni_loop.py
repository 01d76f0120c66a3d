"""The same loop as examples/c/01_omni_loop.c, from Python: the Omni's handle held to a
circle in the x-y plane (the paper's Fig. 4 mechanism). Prints the joint torques."""

import numpy as np

import virtmech as vm

omni = vm.PhantomOmni()
circle = vm.PlanarArm(pivot=[0.0, 0.0, -0.1], normal=[0, 0, 1], length=0.05)
controller = vm.Controller(omni, circle)

print(f"virtmech {vm.__version__}, Omni + PlanarArm")
print(f"{'t [s]':>8} {'tau0':>10} {'tau1':>10} {'tau2':>10} {'|f| [N]':>8}  status")
for k in range(1001):
    t = k * 1e-3
    q = np.array([0.2 * np.sin(2 * t), 0.5 + 0.1 * np.sin(3 * t), 0.3, 0.0, 0.6, 0.0])
    dq = np.array([0.4 * np.cos(2 * t), 0.3 * np.cos(3 * t), 0.0, 0.0, 0.0, 0.0])
    out = controller.step(q, dq, t)
    if k % 100 == 0:
        tau = out.torque
        print(
            f"{t:8.3f} {tau[0]:10.5f} {tau[1]:10.5f} {tau[2]:10.5f} "
            f"{np.linalg.norm(out.wrench[:3]):8.4f}  {','.join(out.status_names) or 'ok'}"
        )
