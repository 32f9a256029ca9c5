#include "io/formats/data_lines.h"

namespace flysfm {

void ForEachDataLine(std::istream& in,
                     const std::function<void(const std::string& line, int number)>& handle) {
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    handle(line, number);
  }
}

}  // namespace flysfm
