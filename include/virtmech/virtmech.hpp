// virtmech: haptic devices, fully or under-actuated, rendered as virtual mechanisms.
#pragma once

#include "virtmech/cartesian_device.hpp"
#include "virtmech/controller.hpp"
#include "virtmech/device.hpp"
#include "virtmech/device_pose.hpp"
#include "virtmech/filters.hpp"
#include "virtmech/geometry.hpp"
#include "virtmech/kinematic_chain.hpp"
#include "virtmech/mechanism.hpp"
#include "virtmech/mechanism_set.hpp"
#include "virtmech/passivity.hpp"
#include "virtmech/se3.hpp"
#include "virtmech/track.hpp"
#include "virtmech/types.hpp"
#include "virtmech/version.hpp"
