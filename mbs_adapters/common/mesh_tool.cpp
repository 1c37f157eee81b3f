#include "mesh_tool.hpp"

#include <cosim/files.hpp>

#include <iostream>
#include <new>
#include <stdexcept>

namespace mbs {

int mesh_tool_main(int argc, char** argv, const std::string& program, const std::function<void()>& usage,
                   const std::function<bool(const std::string& flag, const std::function<std::string()>& value)>& option,
                   const std::function<void(const MeshToolArgs& args)>& run) {
  MeshToolArgs args;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      const std::function<std::string()> value = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "--output") args.output = value();
      else if (a == "--config") args.config = value();
      else if (a == "--help" || a == "-h") {
        usage();
        return 0;
      } else if (!option(a, value)) {
        throw std::invalid_argument("unknown argument '" + a + "'");
      }
    }
    if (args.output.empty()) throw std::invalid_argument("--output is required");
    cosim::check_output_files({{"--output", args.output}}, {{"--config", args.config}});
    run(args);
  } catch (const std::bad_alloc&) {
    std::cerr << program << ": out of memory (std::bad_alloc): give it more memory or a coarser "
                            "mesh\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << program << ": " << e.what() << "\n";
    usage();
    return 2;
  }
  return 0;
}

}  // namespace mbs
