#pragma once

// Line-oriented text data files with '#' comments, as TUM RGB-D writes them
// (rgb.txt, groundtruth.txt, trajectories).

#include <functional>
#include <istream>
#include <string>

namespace flysfm {

// Calls `handle(line, number)` for every line of `in` that is neither blank
// nor a '#' comment; `number` counts all lines from 1, so that a message can
// name the offending one.
void ForEachDataLine(std::istream& in,
                     const std::function<void(const std::string& line, int number)>& handle);

}  // namespace flysfm
