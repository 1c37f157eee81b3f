// An FMU's binary, opened with RTLD_LOCAL (two FMUs that export the same fmi* names never see
// each other's symbols), its functions looked up by name, closed when it goes. Shared by the
// FMI 2.0 and 3.0 libraries (fmi2_instance.hpp, fmi3_instance.hpp).
#pragma once

#include <string>

namespace fmu {

class SharedLibrary {
 public:
  // Loads `so_path`; `fmu` names the FMU in messages, `platform` the binary folder it came from.
  // Raises FmuError when the file cannot be loaded.
  SharedLibrary(const std::string& so_path, const std::string& fmu, const std::string& platform);
  ~SharedLibrary();
  SharedLibrary(const SharedLibrary&) = delete;
  SharedLibrary& operator=(const SharedLibrary&) = delete;

  // Sets `fn` to the function `name`, or to nullptr when the binary has none; a required one
  // that is missing is listed for check_complete.
  template <class F>
  void find(F*& fn, const char* name, bool required) {
    void* p = symbol(name);
    fn = reinterpret_cast<F*>(p);
    if (!p && required) missing_ += (missing_.empty() ? "" : ", ") + std::string(name);
  }
  // Raises FmuError naming every required function that find did not find; `what` says what a
  // binary without them is likely to be.
  void check_complete(const std::string& what) const;

 private:
  void* symbol(const char* name);

  void* handle_ = nullptr;
  std::string path_, fmu_, missing_;
};

}  // namespace fmu
