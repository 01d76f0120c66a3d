// Plugins: shared libraries adding kinds to the process's registry (include/virtmech/registry.hpp).
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>

#include "virtmech/registry.hpp"

#if defined(_WIN32)
#error "virtmech plugins are loaded with dlopen (Linux, macOS)"
#else
#include <dlfcn.h>
#include <sys/stat.h>
#include <climits>
#include <cstdlib>
#endif

namespace virtmech {

namespace {

std::string canonical(const std::string& path) {
  char resolved[PATH_MAX];
  if (!realpath(path.c_str(), resolved)) {
    throw std::invalid_argument(path + ": no such plugin file; expected the path of a shared "
                                "library built with VIRTMECH_PLUGIN");
  }
  return resolved;
}

std::string last_dl_error() {
  const char* e = dlerror();
  return e ? e : "unknown error";
}

}  // namespace

void load_plugin(const std::string& path) {
  static std::mutex mutex;
  static std::set<std::string> loaded;
  std::lock_guard<std::mutex> lock(mutex);
  const std::string file = canonical(path);
  if (loaded.count(file)) return;
  // RTLD_LOCAL: the plugin's own copy of the core stays its own; never closed, its kinds'
  // code lives as long as the registry
  void* handle = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!handle) {
    throw std::invalid_argument(path + ": cannot be loaded as a plugin (" + last_dl_error() + ")");
  }
  using AbiFunction = const char* (*)();
  using RegisterFunction = void (*)(Registry*);
  auto abi = reinterpret_cast<AbiFunction>(dlsym(handle, "virtmech_plugin_abi"));
  auto add = reinterpret_cast<RegisterFunction>(dlsym(handle, "virtmech_plugin_register"));
  if (!abi || !add) {
    dlclose(handle);
    throw std::invalid_argument(path + ": not a virtmech plugin (no virtmech_plugin_abi or "
                                "virtmech_plugin_register; declare them with VIRTMECH_PLUGIN)");
  }
  const std::string theirs = abi(), ours = VIRTMECH_ABI_TAG;
  if (theirs != ours) {
    dlclose(handle);
    throw std::invalid_argument(path + ": built against " + theirs + ", but this virtmech is " +
                                ours + "; rebuild the plugin against this virtmech's headers "
                                "(python -m virtmech --cmake-dir)");
  }
  add(&registry());
  loaded.insert(file);
}

}  // namespace virtmech
