// The C++ objects behind the C API's handles (defined in c_api.cpp), for the other C API
// sources (src/drivers/c_api_driver.cpp).
#pragma once

#include "virtmech.h"
#include "virtmech/controller.hpp"
#include "virtmech/mechanism_set.hpp"

namespace virtmech::detail {

Controller& controller_of(vm_controller* controller) noexcept;
MechanismSet& set_of(vm_mechanism_set* set) noexcept;

}  // namespace virtmech::detail
