// The command line of a machine's mesh generator (bucket_mesh, body_mesh):
//   PROGRAM --output FILE.stl [--config MACHINE.yaml] [the tool's own options] [--help]
#pragma once

#include <functional>
#include <string>

namespace mbs {

struct MeshToolArgs {
  std::string output;  // required
  std::string config;  // "" for the built-in shape
};

// option(flag, value) reads one of the tool's own options and returns false for a flag it does
// not know; value() takes the flag's value (and raises when there is none). run(args) makes and
// writes the mesh. A bad command line or an error in run: "PROGRAM: message", the usage, exit
// code 2; --help: the usage, exit code 0.
int mesh_tool_main(int argc, char** argv, const std::string& program, const std::function<void()>& usage,
                   const std::function<bool(const std::string& flag, const std::function<std::string()>& value)>& option,
                   const std::function<void(const MeshToolArgs& args)>& run);

}  // namespace mbs
