// body_mesh --output FILE.stl [--config machine.yaml] [--element H]
// Writes the dump body's inner shell as a binary STL in the body frame (docs/hauler.md).
#include <cosim/number_arg.hpp>
#include <cosim/yaml_config.hpp>

#include <cstdio>
#include <iostream>
#include <string>

#include "body_mesh.hpp"
#include "mesh_tool.hpp"

namespace {
void usage() {
  std::cerr << "usage: body_mesh --output FILE.stl [--config MACHINE.yaml] [--element H]\n"
               "  --config   take dump_body.shape from a machine config "
               "(default: the built-in shape = configs/hauler/machine.yaml)\n"
               "  --element  target edge length [m], 0.02..1 (default 0.2)\n";
}
}  // namespace

int main(int argc, char** argv) {
  double element = 0.2;
  auto option = [&](const std::string& a, const std::function<std::string()>& value) {
    if (a != "--element") return false;
    element = cosim::parse_number_arg(a, value(), "an edge length in m, 0.02..1 (e.g. 0.2)", 0.02, 1.0);
    return true;
  };
  return mbs::mesh_tool_main(argc, argv, "body_mesh", usage, option, [&](const mbs::MeshToolArgs& args) {
    hauler::BodyShape shape;
    if (!args.config.empty()) shape = hauler::read_parameters(cosim::config::load_file(args.config)).shape;
    const auto mesh = hauler::make_body_mesh(shape, element);
    hauler::write_stl(mesh, args.output);
    std::printf("body_mesh: %s: %zu triangles, %zu vertices, inner %.3f x %.3f x %.3f m, %.2f m3 "
                "(body frame: origin hinge axis, floor z = %.3f, tail x = %.3f, front wall x = %.3f)\n",
                args.output.c_str(), mesh.triangles.size(), mesh.vertices.size(), shape.length,
                shape.width, shape.side_height, mesh.volume, shape.floor_z, shape.tail_x,
                shape.front_x());
  });
}
