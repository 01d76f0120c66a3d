// A vendor library loaded at run time (dlopen) into its table of functions: what the SDK
// loaders (hd_api.cpp, dhd_api.cpp) share.
#pragma once

#include <dlfcn.h>

#include <cstddef>
#include <cstdio>
#include <string>

namespace virtmech::drivers::detail {

/// `message` into the caller's buffer (nothing where it has none).
inline void put_error(char* error, std::size_t size, const std::string& message) {
  if (error == nullptr || size == 0) return;
  std::snprintf(error, size, "%s", message.c_str());
}

/// dlopen(path), then resolve(handle, missing) fills the table `api` (returning false with
/// the first function missing named); on success api->library and api->path are set. On
/// failure the reason is in `why` (the loader's, or the function missing: "not the <what>"),
/// the library is closed and `api` zeroed.
template <typename Api, typename Resolve>
bool load_library(const std::string& path, Api* api, const char* what, Resolve resolve,
                  std::string& why) {
  dlerror();
  void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* e = dlerror();
    why = e ? e : "cannot be loaded";
    return false;
  }
  std::string missing;
  if (!resolve(handle, missing)) {
    why = "it has no function " + missing + ": not the " + what;
    dlclose(handle);
    *api = Api{};
    return false;
  }
  api->library = handle;
  std::snprintf(api->path, sizeof api->path, "%s", path.c_str());
  return true;
}

}  // namespace virtmech::drivers::detail
