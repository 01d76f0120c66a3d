// vm_hd_load: the OpenHaptics HD library loaded at run time (virtmech/drivers/hd_api.h).
#include "virtmech/drivers/hd_api.h"

#include "library_loader.hpp"

#include <dlfcn.h>
#include <glob.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

using virtmech::drivers::detail::put_error;

// the library's files under the OpenHaptics install folders, newest version last
std::vector<std::string> install_candidates() {
  std::vector<std::string> out;
  for (const char* pattern :
       {"/opt/OpenHaptics/Developer/*/lib/libHD.so*", "/opt/OpenHaptics/lib/libHD.so*",
        "/opt/OpenHaptics/Academic/*/lib/libHD.so*"}) {
    glob_t g{};
    if (glob(pattern, 0, nullptr, &g) == 0) {
      for (size_t i = 0; i < g.gl_pathc; ++i) out.emplace_back(g.gl_pathv[i]);
    }
    globfree(&g);
  }
  return out;
}

// every function of VM_HD_FUNCTIONS from `handle`; false with the first missing one named
bool resolve(void* handle, vm_hd_api* api, std::string& missing) {
#define VM_HD_RESOLVE(ret, name, params)                                            \
  api->name = reinterpret_cast<ret(*) params>(dlsym(handle, #name));                \
  if (api->name == nullptr) {                                                       \
    missing = #name;                                                                \
    return false;                                                                   \
  }
  VM_HD_FUNCTIONS(VM_HD_RESOLVE)
#undef VM_HD_RESOLVE
  return true;
}

// dlopen + resolve; the reason in `why` on failure
bool try_load(const std::string& path, vm_hd_api* api, std::string& why) {
  auto resolve_api = [api](void* handle, std::string& missing) {
    return resolve(handle, api, missing);
  };
  return virtmech::drivers::detail::load_library(path, api, "OpenHaptics HD library",
                                                 resolve_api, why);
}

const char* const kInstall =
    "install OpenHaptics for Linux (3D Systems' developer edition, which installs libHD.so) "
    "and the Touch device driver";

}  // namespace

extern "C" int vm_hd_load(const char* path, vm_hd_api* api, char* error, size_t error_size) {
  if (api == nullptr) {
    put_error(error, error_size, "api: expected a vm_hd_api to fill, got NULL");
    return -1;
  }
  *api = vm_hd_api{};
  std::string why;
  if (path != nullptr && path[0] != '\0') {
    if (try_load(path, api, why)) return 0;
    put_error(error, error_size,
              std::string(path) + ": cannot be loaded as the HD library (" + why + "); " +
                  kInstall + ", or give the path of its libHD.so");
    return -1;
  }
  std::vector<std::string> tried{"libHD.so"};
  if (try_load("libHD.so", api, why)) return 0;
  for (const std::string& candidate : install_candidates()) {
    tried.push_back(candidate);
    if (try_load(candidate, api, why)) return 0;
  }
  put_error(error, error_size,
            std::string("libHD.so: not found on the loader's search path (LD_LIBRARY_PATH, "
                        "the system's libraries) nor under /opt/OpenHaptics; ") +
                kInstall + ", or give the path of its libHD.so");
  return -1;
}

extern "C" void vm_hd_unload(vm_hd_api* api) {
  if (api == nullptr) return;
  if (api->library != nullptr) dlclose(api->library);
  *api = vm_hd_api{};
}

extern "C" const char* vm_hd_error_name(HDerror code) {
  switch (code) {
#define VM_HD_NAME(c) \
  case c:             \
    return #c;
    VM_HD_NAME(HD_SUCCESS)
    VM_HD_NAME(HD_INVALID_ENUM)
    VM_HD_NAME(HD_INVALID_VALUE)
    VM_HD_NAME(HD_INVALID_OPERATION)
    VM_HD_NAME(HD_INVALID_INPUT_TYPE)
    VM_HD_NAME(HD_BAD_HANDLE)
    VM_HD_NAME(HD_WARM_MOTORS)
    VM_HD_NAME(HD_EXCEEDED_MAX_FORCE)
    VM_HD_NAME(HD_EXCEEDED_MAX_FORCE_IMPULSE)
    VM_HD_NAME(HD_EXCEEDED_MAX_VELOCITY)
    VM_HD_NAME(HD_FORCE_ERROR)
    VM_HD_NAME(HD_DEVICE_FAULT)
    VM_HD_NAME(HD_DEVICE_ALREADY_INITIATED)
    VM_HD_NAME(HD_COMM_ERROR)
    VM_HD_NAME(HD_COMM_CONFIG_ERROR)
    VM_HD_NAME(HD_TIMER_ERROR)
    VM_HD_NAME(HD_ILLEGAL_BEGIN)
    VM_HD_NAME(HD_ILLEGAL_END)
    VM_HD_NAME(HD_FRAME_ERROR)
    VM_HD_NAME(HD_INVALID_PRIORITY)
    VM_HD_NAME(HD_SCHEDULER_FULL)
    VM_HD_NAME(HD_INVALID_LICENSE)
#undef VM_HD_NAME
    default:
      return nullptr;
  }
}
