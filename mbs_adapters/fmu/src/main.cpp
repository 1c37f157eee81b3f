// fmu_adapter: an FMI 2.0 or 3.0 co-simulation FMU as a participant (docs/fmi.md).
//   fmu_adapter CONFIG.yaml [--set dotted.key=value ...] [--name NAME] [--bus URL] ...
//   fmu_adapter MODEL.fmu --mapping MAPPING.yaml [--set ...] [--name NAME] [--bus URL] ...
// CONFIG.yaml (or MAPPING.yaml with the FMU given apart) holds the mapping; the master's
// `parameters` amend it (or give it all).
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>

#include "cosim/yaml_config.hpp"
#include "fmu_model.hpp"

namespace {

void usage() {
  std::cerr << "usage: fmu_adapter CONFIG.yaml [--set dotted.key=value ...] [--name NAME] [--bus URL]\n"
               "       fmu_adapter MODEL.fmu --mapping MAPPING.yaml [--set ...] [--name NAME] [--bus URL]\n"
               "       fmu_adapter [--name NAME] ...   (everything from the master's parameters)\n"
               "The mapping's keys: docs/fmi.md.\n";
}

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

}  // namespace

int main(int argc, char** argv) {
  // Several processes share one log: a line must reach it in one write, not one per <<.
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
  std::string fmu_file, mapping, name = "fmu";
  std::vector<char*> args{argv[0]};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    }
    if (a == "--mapping") {
      if (i + 1 >= argc) {
        std::cerr << "fmu_adapter: --mapping needs a file\n";
        usage();
        return 2;
      }
      mapping = argv[++i];
    } else if (ends_with(a, ".fmu") && a[0] != '-' && fmu_file.empty()) {
      fmu_file = a;
    } else {
      if (a == "--name" && i + 1 < argc) name = argv[i + 1];
      args.push_back(argv[i]);
    }
  }
  if (!mapping.empty()) args.insert(args.begin() + 1, mapping.data());
  std::string config_path;
  try {
    auto parsed = cosim::parse_participant_args(static_cast<int>(args.size()), args.data(), false);
    if (!fmu_file.empty()) {
      if (parsed.config["fmu"])
        throw cosim::config::ConfigError("the FMU is given twice: " + fmu_file + " on the command line and fmu: in " +
                                         parsed.config_path);
      parsed.config["fmu"] = std::filesystem::absolute(fmu_file).string();
    }
    config_path = parsed.config_path;
    fmu::FmuModel model(parsed.config, parsed.config_dir);
    // With the FMU named already, check it and the mapping now: a broken FMU is reported when
    // the adapter starts, not only when a master connects.
    if (parsed.config["fmu"])
      model.prepare(YAML::Node(YAML::NodeType::Map), name, true);
    return cosim::run_participant(model, "fmu", static_cast<int>(parsed.rest.size()), parsed.rest.data());
  } catch (const cosim::config::ConfigError& e) {
    std::cerr << "fmu_adapter: config error" << (config_path.empty() ? "" : " in " + config_path) << ": " << e.what() << "\n";
    return 2;
  } catch (const fmu::FmuError& e) {
    std::cerr << "fmu_adapter: " << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << cosim::out_of_memory_message("fmu_adapter") << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "fmu_adapter: error: " << e.what() << "\n";
    return 1;
  }
}
