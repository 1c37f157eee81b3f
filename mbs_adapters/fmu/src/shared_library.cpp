#include "shared_library.hpp"

#include <dlfcn.h>

#include "model_description.hpp"

namespace fmu {

SharedLibrary::SharedLibrary(const std::string& so_path, const std::string& fmu, const std::string& platform)
    : path_(so_path), fmu_(fmu) {
  handle_ = dlopen(so_path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!handle_) {
    const char* e = dlerror();
    throw FmuError("FMU '" + fmu + "': cannot load its binary " + so_path + ": " + (e ? e : "unknown error") +
                   " (is it built for " + platform + " and are the libraries it needs installed?)");
  }
}

SharedLibrary::~SharedLibrary() {
  if (handle_) dlclose(handle_);
}

void* SharedLibrary::symbol(const char* name) {
  dlerror();
  return dlsym(handle_, name);
}

void SharedLibrary::check_complete(const std::string& what) const {
  if (!missing_.empty())
    throw FmuError("FMU '" + fmu_ + "': its binary " + path_ + " does not export " + missing_ + " (" + what + ")");
}

}  // namespace fmu
