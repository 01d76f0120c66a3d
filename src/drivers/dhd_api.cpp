// vm_dhd_load: the Force Dimension DHD library loaded at run time (virtmech/drivers/dhd_api.h).
#include "virtmech/drivers/dhd_api.h"

#include "library_loader.hpp"

#include <dlfcn.h>

#include <cstdio>
#include <string>

namespace {

using virtmech::drivers::detail::put_error;

// every function of VM_DHD_FUNCTIONS from `handle`; false with the first missing one named
bool resolve(void* handle, vm_dhd_api* api, std::string& missing) {
#define VM_DHD_RESOLVE(ret, name, params)                              \
  api->name = reinterpret_cast<ret(*) params>(dlsym(handle, #name));   \
  if (api->name == nullptr) {                                          \
    missing = #name;                                                   \
    return false;                                                      \
  }
  VM_DHD_FUNCTIONS(VM_DHD_RESOLVE)
#undef VM_DHD_RESOLVE
  return true;
}

bool try_load(const std::string& path, vm_dhd_api* api, std::string& why) {
  auto resolve_api = [api](void* handle, std::string& missing) {
    return resolve(handle, api, missing);
  };
  return virtmech::drivers::detail::load_library(path, api, "Force Dimension DHD library",
                                                 resolve_api, why);
}

const char* const kInstall =
    "install the Force Dimension SDK (its lib/release folder holds libdhd.so; the Novint Falcon "
    "is served by the same SDK) and put that folder on LD_LIBRARY_PATH";

}  // namespace

extern "C" int vm_dhd_load(const char* path, vm_dhd_api* api, char* error, size_t error_size) {
  if (api == nullptr) {
    put_error(error, error_size, "api: expected a vm_dhd_api to fill, got NULL");
    return -1;
  }
  *api = vm_dhd_api{};
  const bool given = path != nullptr && path[0] != '\0';
  const std::string file = given ? path : "libdhd.so";
  std::string why;
  if (try_load(file, api, why)) return 0;
  put_error(error, error_size,
            file + ": cannot be loaded as the DHD library (" + why + "); " + kInstall +
                (given ? ", or give the path of its libdhd.so" : ", or give its path (--library)"));
  return -1;
}

extern "C" void vm_dhd_unload(vm_dhd_api* api) {
  if (api == nullptr) return;
  if (api->library != nullptr) dlclose(api->library);
  *api = vm_dhd_api{};
}

extern "C" const char* vm_dhd_model_name(int system_type) {
  switch (system_type) {
    case VM_DHD_OMEGA3:
      return "omega.3";
    case VM_DHD_OMEGA6_RIGHT:
    case VM_DHD_OMEGA6_LEFT:
      return "omega.6";
    case VM_DHD_OMEGA7_RIGHT:
    case VM_DHD_OMEGA7_LEFT:
      return "omega.7";
    case VM_DHD_SIGMA7_RIGHT:
    case VM_DHD_SIGMA7_LEFT:
      return "sigma.7";
    case VM_DHD_FALCON:
      return "falcon";
    default:
      return nullptr;
  }
}

extern "C" const char* vm_dhd_system_name(int system_type) {
  if (system_type == VM_DHD_DELTA3) return "delta.3";
  return vm_dhd_model_name(system_type);
}
