// A plugin built against other headers: its ABI tag is not this virtmech's, so the host
// refuses it before running its registration (which would abort the test).
#include <cstdlib>

extern "C" __attribute__((visibility("default"))) const char* virtmech_plugin_abi() {
  return "virtmech 0.0.1; registry 0; another build";
}

extern "C" __attribute__((visibility("default"))) void virtmech_plugin_register(void*) {
  std::abort();
}
