// C-API versions of the test shapes and scenes (defined in test_c_api_shapes.cpp, used there
// and by test_allocation.cpp): the C arrays of a NURBS curve / surface, read back from the
// C++ object (the test patch and letter of test_support.hpp), made into a vm_shape;
// vmtest::make_set() of cycle_scenes.hpp built through the C API.
#pragma once

#include "virtmech.h"
#include "virtmech/geometry.hpp"

namespace vmtest {

vm_shape* c_nurbs_curve(const virtmech::NurbsCurve& curve);
vm_shape* c_nurbs_surface(const virtmech::NurbsSurface& surface);
vm_mechanism_set* c_make_set(int capacity);

}  // namespace vmtest
