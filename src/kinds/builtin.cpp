// The list of built-in kinds: a new kind is its own file in this folder and one line here.
#include "kinds.hpp"

namespace virtmech::kinds {

void add_builtin(Registry& r) {
  // curves and surfaces
  add_nurbs_curve(r);
  add_nurbs_surface(r);
  add_sphere(r);
  add_cylinder(r);
  add_plane(r);
  // mechanisms
  add_planar_arm(r);
  add_point_pivot(r);
  add_probe(r);
  add_line_guide(r);
  add_surface_probe(r);
  add_curve_guide(r);
  add_handle_path(r);
  add_serial_chain(r);
  // devices
  add_phantom_omni(r);
  add_planar3r(r);
  add_serial_device(r);
  add_cartesian_device(r);
}

}  // namespace virtmech::kinds
