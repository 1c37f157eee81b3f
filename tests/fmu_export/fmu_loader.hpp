// Test helper: loads an FMU's shared library straight from the build tree with dlopen and
// calls its fmi2 functions the way a master does, collecting what the FMU logs. Not an
// importer (mbs_adapters/fmu is): no unzipping, no XML, just the C interface under test.
#pragma once

#include <cosim_fmi2.h>
#include <dlfcn.h>
#include <gtest/gtest.h>

#include <cstdarg>
#include <cstdio>
#include <fstream>
#include <map>
#include <regex>
#include <utility>
#include <sstream>
#include <string>
#include <vector>

namespace fmu_test {

inline std::string build_fmu_dir() { return std::string(FMU_DIR); }
inline std::string so_path(const std::string& id) { return build_fmu_dir() + "/" + id + "/binaries/linux64/" + id + ".so"; }
inline std::string xml_path(const std::string& id) { return build_fmu_dir() + "/" + id + "/modelDescription.xml"; }

inline std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The GUID and value references as the FMU's modelDescription.xml states them.
inline std::string guid_of(const std::string& id) {
  std::smatch m;
  const std::string xml = read_text(xml_path(id));
  return std::regex_search(xml, m, std::regex("guid=\"([^\"]+)\"")) ? m[1].str() : "";
}
// Looked up once per FMU and name: the tests set and get by name at every step, and reading the
// XML and matching a regex each time was most of their time.
inline fmi2ValueReference vr_of(const std::string& id, const std::string& name) {
  static std::map<std::pair<std::string, std::string>, fmi2ValueReference> known;
  if (const auto it = known.find({id, name}); it != known.end()) return it->second;
  std::smatch m;
  const std::string xml = read_text(xml_path(id));
  if (!std::regex_search(xml, m, std::regex("name=\"" + name + "\" valueReference=\"([0-9]+)\""))) {
    ADD_FAILURE() << id << " declares no variable " << name;
    return 9999;
  }
  const auto vr = static_cast<fmi2ValueReference>(std::stoul(m[1].str()));
  known.emplace(std::pair{id, name}, vr);
  return vr;
}

struct Log {
  std::vector<std::string> lines;
  std::string all() const {
    std::string s;
    for (const auto& l : lines) s += l + "\n";
    return s;
  }
};

extern "C" inline void collect_log(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                                   fmi2String category, fmi2String message, ...) {
  char buf[4096];
  va_list ap;
  va_start(ap, message);
  std::vsnprintf(buf, sizeof buf, message, ap);
  va_end(ap);
  static_cast<Log*>(env)->lines.push_back(std::string(instance ? instance : "?") + " [" + std::to_string(status) +
                                          "] " + (category ? category : "") + ": " + buf);
  if (std::getenv("FMU_TEST_VERBOSE")) std::fprintf(stderr, "%s\n", static_cast<Log*>(env)->lines.back().c_str());
}

// The functions of one loaded FMU binary.
struct Library {
  void* handle = nullptr;
#define FMU_FN(name) name##TYPE* name = nullptr;
  FMU_FN(fmi2GetVersion) FMU_FN(fmi2GetTypesPlatform) FMU_FN(fmi2Instantiate) FMU_FN(fmi2FreeInstance)
  FMU_FN(fmi2SetupExperiment) FMU_FN(fmi2EnterInitializationMode) FMU_FN(fmi2ExitInitializationMode)
  FMU_FN(fmi2Terminate) FMU_FN(fmi2Reset) FMU_FN(fmi2GetReal) FMU_FN(fmi2SetReal) FMU_FN(fmi2GetInteger)
  FMU_FN(fmi2SetInteger) FMU_FN(fmi2GetString) FMU_FN(fmi2SetString) FMU_FN(fmi2GetFMUstate)
  FMU_FN(fmi2SetFMUstate) FMU_FN(fmi2FreeFMUstate) FMU_FN(fmi2SetRealInputDerivatives) FMU_FN(fmi2DoStep) FMU_FN(fmi2SetDebugLogging)
#undef FMU_FN
  explicit Library(const std::string& id) {
    handle = dlopen(so_path(id).c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      ADD_FAILURE() << "dlopen " << so_path(id) << ": " << dlerror();
      return;
    }
#define FMU_FN(name) name = reinterpret_cast<name##TYPE*>(dlsym(handle, #name)); EXPECT_NE(name, nullptr) << #name;
    FMU_FN(fmi2GetVersion) FMU_FN(fmi2GetTypesPlatform) FMU_FN(fmi2Instantiate) FMU_FN(fmi2FreeInstance)
    FMU_FN(fmi2SetupExperiment) FMU_FN(fmi2EnterInitializationMode) FMU_FN(fmi2ExitInitializationMode)
    FMU_FN(fmi2Terminate) FMU_FN(fmi2Reset) FMU_FN(fmi2GetReal) FMU_FN(fmi2SetReal) FMU_FN(fmi2GetInteger)
    FMU_FN(fmi2SetInteger) FMU_FN(fmi2GetString) FMU_FN(fmi2SetString) FMU_FN(fmi2GetFMUstate)
    FMU_FN(fmi2SetFMUstate) FMU_FN(fmi2FreeFMUstate) FMU_FN(fmi2SetRealInputDerivatives) FMU_FN(fmi2DoStep) FMU_FN(fmi2SetDebugLogging)
#undef FMU_FN
  }
  ~Library() {
    if (handle) dlclose(handle);
  }
  Library(const Library&) = delete;
  Library& operator=(const Library&) = delete;
};

// One instance of an FMU, with its log.
struct Instance {
  Library& lib;
  std::string id;
  Log log;
  fmi2CallbackFunctions callbacks{};
  fmi2Component c = nullptr;

  Instance(Library& l, const std::string& fmu_id, const std::string& name = "test", std::string guid = "")
      : lib(l), id(fmu_id) {
    callbacks.logger = collect_log;
    callbacks.componentEnvironment = &log;
    if (guid.empty()) guid = guid_of(id);
    c = lib.fmi2Instantiate(name.c_str(), fmi2CoSimulation, guid.c_str(), "", &callbacks, fmi2False, fmi2False);
  }
  ~Instance() {
    if (c) lib.fmi2FreeInstance(c);
  }
  Instance(const Instance&) = delete;
  Instance& operator=(const Instance&) = delete;

  fmi2ValueReference vr(const std::string& name) const { return vr_of(id, name); }
  fmi2Status set(const std::string& name, double v) {
    const fmi2ValueReference r = vr(name);
    return lib.fmi2SetReal(c, &r, 1, &v);
  }
  fmi2Status set_int(const std::string& name, int v) {
    const fmi2ValueReference r = vr(name);
    return lib.fmi2SetInteger(c, &r, 1, &v);
  }
  fmi2Status set_string(const std::string& name, const std::string& v) {
    const fmi2ValueReference r = vr(name);
    const char* s = v.c_str();
    return lib.fmi2SetString(c, &r, 1, &s);
  }
  fmi2Status set_derivative(const std::string& name, int order, double v) {
    const fmi2ValueReference r = vr(name);
    return lib.fmi2SetRealInputDerivatives(c, &r, 1, &order, &v);
  }
  double get(const std::string& name) {
    const fmi2ValueReference r = vr(name);
    double v = NAN;
    EXPECT_EQ(lib.fmi2GetReal(c, &r, 1, &v), fmi2OK) << name << "\n" << log.all();
    return v;
  }
  // setupExperiment, initialization mode in and out.
  fmi2Status initialize(double start = 0, double stop = -1) {
    fmi2Status s = lib.fmi2SetupExperiment(c, fmi2False, 0, start, stop > start ? fmi2True : fmi2False, stop);
    if (s != fmi2OK) return s;
    if ((s = lib.fmi2EnterInitializationMode(c)) != fmi2OK) return s;
    return lib.fmi2ExitInitializationMode(c);
  }
  fmi2Status step(double t, double h) { return lib.fmi2DoStep(c, t, h, fmi2True); }
};

}  // namespace fmu_test
