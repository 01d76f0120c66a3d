// The C API checks every enumeration a C caller writes as an integer before it becomes a
// C++ enumeration: out-of-range values (type = 99, law = -1, ...) are refused with a message
// naming the field, never converted. Built and run under AddressSanitizer and
// UndefinedBehaviorSanitizer (tests/cpp/sanitized.cmake), where a conversion of an
// out-of-range value would stop the test.
#include <gtest/gtest.h>

#include <climits>
#include <cmath>
#include <string>

#include "virtmech.h"

namespace {

struct Made {
  int rc;
  std::string error;
};

Made create(const vm_device_desc& dev, const vm_mechanism_desc& mech, const vm_settings* s) {
  vm_controller* c = nullptr;
  char err[512];
  const int rc = vm_controller_create(&dev, &mech, s, &c, err, sizeof err);
  if (rc == VM_OK) {
    double q[VM_MAX_DOF] = {0.1, 0.5, 0.2, 0.0, 0.6, 0.0}, dq[VM_MAX_DOF] = {0}, tau[VM_MAX_DOF];
    vm_controller_step(c, q, dq, vm_controller_dof(c), NAN, tau);
  } else {
    EXPECT_EQ(c, nullptr);
  }
  vm_controller_destroy(c);
  return {rc, err};
}

vm_device_desc omni() {
  vm_device_desc d;
  vm_device_desc_init(&d, VM_DEVICE_PHANTOM_OMNI);
  return d;
}

vm_mechanism_desc arm() {
  vm_mechanism_desc m;
  vm_mechanism_desc_init(&m, VM_MECHANISM_PLANAR_ARM);
  m.point[2] = -0.05;
  m.length = 0.05;
  return m;
}

bool starts_with(const std::string& s, const std::string& prefix) {
  return s.rfind(prefix, 0) == 0;
}

const int kBad[] = {-1, 3, 8, 99, INT_MAX, INT_MIN};

}  // namespace

TEST(CApiEnums, GoodValuesOfEveryEnumerationAreAccepted) {
  for (int law : {VM_LAW_AUTO, VM_LAW_NULL_SPACE, VM_LAW_UNDER_ACTUATED}) {
    for (int ev : {VM_ERROR_VELOCITY_RELATIVE, VM_ERROR_VELOCITY_HANDLE}) {
      for (int p : {VM_PASSIVITY_OFF, VM_PASSIVITY_ENERGY_TANK}) {
        vm_settings s;
        vm_settings_init(&s);
        s.law = law;
        s.error_velocity = ev;
        s.passivity = p;
        EXPECT_EQ(create(omni(), arm(), &s).rc, VM_OK) << law << " " << ev << " " << p;
      }
    }
  }
}

TEST(CApiEnums, SettingsEnumerationsOutOfRangeAreRefusedNamingTheField) {
  for (int bad : kBad) {
    for (const char* field : {"law", "error_velocity", "passivity"}) {
      vm_settings s;
      vm_settings_init(&s);
      int* target = std::string(field) == "law"              ? &s.law
                    : std::string(field) == "error_velocity" ? &s.error_velocity
                                                             : &s.passivity;
      *target = bad;
      const Made m = create(omni(), arm(), &s);
      EXPECT_EQ(m.rc, VM_ERROR_ARGUMENT) << field << " = " << bad;
      EXPECT_TRUE(starts_with(m.error, std::string("settings.") + field + ": expected ")) << m.error;
      EXPECT_NE(m.error.find("got " + std::to_string(bad)), std::string::npos) << m.error;
    }
  }
  vm_settings s;
  vm_settings_init(&s);
  s.law = 99;
  EXPECT_EQ(create(omni(), arm(), &s).error,
            "settings.law: expected 0 (auto), 1 (null_space) or 2 (under_actuated), got 99");
}

TEST(CApiEnums, DeviceAndMechanismTypesOutOfRangeAreRefusedNamingTheField) {
  for (int bad : kBad) {
    vm_device_desc d;
    vm_device_desc_init(&d, bad);  // the type is stored as given; nothing else is set for it
    EXPECT_EQ(d.type, bad);
    Made m = create(d, arm(), nullptr);
    EXPECT_EQ(m.rc, VM_ERROR_ARGUMENT);
    EXPECT_TRUE(starts_with(m.error, "device.type: expected ")) << m.error;

    if (bad >= VM_MECHANISM_PLANAR_ARM && bad <= VM_MECHANISM_HANDLE_PATH) continue;  // a type
    vm_mechanism_desc a;
    vm_mechanism_desc_init(&a, bad);
    m = create(omni(), a, nullptr);
    EXPECT_EQ(m.rc, VM_ERROR_ARGUMENT);
    EXPECT_TRUE(starts_with(m.error, "mechanism.type: expected ")) << m.error;
  }
}

TEST(CApiEnums, JointTypesOutOfRangeAreRefusedNamingTheJoint) {
  vm_device_desc d;
  vm_device_desc_init(&d, VM_DEVICE_SERIAL);
  d.chain.dof = 2;
  d.actuated[0] = d.actuated[1] = 1;
  for (int bad : kBad) {
    d.chain.joints[1].type = bad;
    const Made m = create(d, arm(), nullptr);
    EXPECT_EQ(m.rc, VM_ERROR_ARGUMENT);
    EXPECT_TRUE(starts_with(m.error, "device.chain.joints[1].type: expected ")) << m.error;
  }
}

TEST(CApiEnums, MechanismSetMembersCheckTheirSettingsToo) {
  vm_device_desc d = omni();
  vm_mechanism_set* set = nullptr;
  char err[512];
  ASSERT_EQ(vm_mechanism_set_create(&d, 2, nullptr, &set, err, sizeof err), VM_OK) << err;
  vm_settings s;
  vm_settings_init(&s);
  s.passivity = -7;
  const vm_mechanism_desc a = arm();
  EXPECT_EQ(vm_mechanism_set_add(set, &a, &s, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_TRUE(starts_with(err, "settings.passivity: expected ")) << err;
  s.passivity = VM_PASSIVITY_OFF;
  EXPECT_EQ(vm_mechanism_set_add(set, &a, &s, err, sizeof err), 0) << err;
  vm_mechanism_set_destroy(set);
}
