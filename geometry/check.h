#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

// An internal invariant that must hold whatever the input: a failure is a bug,
// not bad data, and stays on in Release builds. Bad input from outside is
// reported through return values or std::invalid_argument, never through this.
#define FLYSFM_CHECK(condition)                                          \
  do {                                                                   \
    if (!(condition)) {                                                  \
      throw std::logic_error(std::string(__FILE__) + ":" +               \
                             std::to_string(__LINE__) +                  \
                             ": check failed: " #condition);             \
    }                                                                    \
  } while (false)
