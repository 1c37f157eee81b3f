// body_mesh --output FILE.stl [--config machine.yaml] [--element H]
// Writes the dump body's inner shell as a binary STL in the body frame (docs/hauler.md).
#include <cosim/files.hpp>
#include <cosim/number_arg.hpp>
#include <cosim/yaml_config.hpp>

#include <cstdio>
#include <iostream>
#include <string>

#include "body_mesh.hpp"

namespace {
void usage() {
  std::cerr << "usage: body_mesh --output FILE.stl [--config MACHINE.yaml] [--element H]\n"
               "  --config   take dump_body.shape from a machine config "
               "(default: the built-in shape = configs/hauler/machine.yaml)\n"
               "  --element  target edge length [m], 0.02..1 (default 0.2)\n";
}
}  // namespace

int main(int argc, char** argv) {
  std::string output, config;
  double element = 0.2;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto value = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "--output") output = value();
      else if (a == "--config") config = value();
      else if (a == "--element")
        element = cosim::parse_number_arg(a, value(), "an edge length in m, 0.02..1 (e.g. 0.2)", 0.02, 1.0);
      else if (a == "--help" || a == "-h") { usage(); return 0; }
      else throw std::invalid_argument("unknown argument '" + a + "'");
    }
    if (output.empty()) throw std::invalid_argument("--output is required");
    cosim::check_output_files({{"--output", output}}, {{"--config", config}});
    hauler::BodyShape shape;
    if (!config.empty()) shape = hauler::read_parameters(cosim::config::load_file(config)).shape;
    const auto mesh = hauler::make_body_mesh(shape, element);
    hauler::write_stl(mesh, output);
    std::printf("body_mesh: %s: %zu triangles, %zu vertices, inner %.3f x %.3f x %.3f m, %.2f m3 "
                "(body frame: origin hinge axis, floor z = %.3f, tail x = %.3f, front wall x = %.3f)\n",
                output.c_str(), mesh.triangles.size(), mesh.vertices.size(), shape.length,
                shape.width, shape.side_height, mesh.volume, shape.floor_z, shape.tail_x,
                shape.front_x());
  } catch (const std::exception& e) {
    std::cerr << "body_mesh: " << e.what() << "\n";
    usage();
    return 2;
  }
  return 0;
}
