// oscillator_adapter --side mass1|mass2 [--name NAME] [--bus URL] ...
#include <cstdio>
#include <cstring>
#include <iostream>

#include "oscillator_adapter.hpp"

int main(int argc, char** argv) {
  // Several processes share one log: a line must reach it in one write, not one per <<.
  std::setvbuf(stderr, nullptr, _IOLBF, 1 << 14);
  std::string side;
  std::vector<char*> rest{argv[0]};
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--side") == 0 && i + 1 < argc) side = argv[++i];
    else rest.push_back(argv[i]);
  }
  if (side != "mass1" && side != "mass2") {
    std::cerr << "oscillator_adapter: --side must be mass1 or mass2 (got '" << side << "')\n"
              << "usage: oscillator_adapter --side mass1|mass2 [--name NAME] [--bus URL]\n";
    return 2;
  }
  return cosim::participant_main("oscillator_adapter", [&] {
    oscillator::OscillatorAdapter model(side == "mass1" ? oscillator::Side::Mass1
                                                      : oscillator::Side::Mass2);
    return cosim::run_participant(model, side, static_cast<int>(rest.size()), rest.data());
  });
}
