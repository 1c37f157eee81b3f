// bucket_mesh --output FILE.stl [--refine 1..4] [--config machine.yaml] [--width W]
// Writes the bucket shell as a binary STL in the bucket frame (docs/wheel_loader.md).
#include <cosim/number_arg.hpp>
#include <cosim/yaml_config.hpp>

#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <string>

#include "bucket_mesh.hpp"
#include "mesh_tool.hpp"

namespace {
void usage() {
  std::cerr << "usage: bucket_mesh --output FILE.stl [--refine 1.." << wheel_loader::kMaxRefine
            << "] [--config MACHINE.yaml] [--width W]\n"
               "  --refine  element size 0.1/N m: 1 (default) a few thousand triangles, "
            << wheel_loader::kMaxRefine
            << " about 40,000\n"
               "  --config  take bucket.shape from a machine config "
               "(default: the built-in shape = configs/wheel_loader/machine.yaml)\n"
               "  --width   override the bucket width [m]\n";
}
}  // namespace

int main(int argc, char** argv) {
  int refine = 1;
  double width = 0;
  auto option = [&](const std::string& a, const std::function<std::string()>& value) {
    if (a == "--refine")
      refine = static_cast<int>(cosim::parse_integer_arg(
          a, value(), "a whole number 1.." + std::to_string(wheel_loader::kMaxRefine), 1,
          wheel_loader::kMaxRefine));
    else if (a == "--width")
      width = cosim::parse_number_arg(a, value(), "a width in m > 0 (e.g. 2.5)");
    else
      return false;
    return true;
  };
  return mbs::mesh_tool_main(argc, argv, "bucket_mesh", usage, option, [&](const mbs::MeshToolArgs& args) {
    if (refine < 1 || refine > wheel_loader::kMaxRefine)
      throw std::invalid_argument("--refine must be 1.." + std::to_string(wheel_loader::kMaxRefine));
    wheel_loader::BucketShape shape;
    if (!args.config.empty()) shape = wheel_loader::read_parameters(cosim::config::load_file(args.config)).shape;
    if (width != 0) {
      if (!(width > 0)) throw std::invalid_argument("--width must be > 0");
      shape.width = width;
    }
    const auto mesh = wheel_loader::make_bucket_mesh(shape, refine);
    wheel_loader::write_stl(mesh, args.output);
    std::printf("bucket_mesh: %s: %zu triangles, %zu vertices, width %.3f m, struck %.2f m3, "
                "heaped %.2f m3 (bucket frame: origin A-pin, cutting edge at x = %.3f, z = %.3f)\n",
                args.output.c_str(), mesh.triangles.size(), mesh.vertices.size(), shape.width,
                mesh.struck_volume, mesh.heaped_volume, shape.edge_x, shape.floor_z);
  });
}
