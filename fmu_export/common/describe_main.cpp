// <id>_describe OUTPUT.xml: writes the FMU's modelDescription.xml from its variable table
// (a build step of soil_add_fmu, cmake/Fmu.cmake).
#include <fstream>
#include <iostream>

#include "description.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: " << argv[0] << " OUTPUT.xml\n";
    return 2;
  }
  std::ofstream out(argv[1]);
  out << fmu_export::model_description_xml(fmu_export::description());
  if (!out) {
    std::cerr << argv[0] << ": cannot write " << argv[1] << "\n";
    return 1;
  }
  return 0;
}
