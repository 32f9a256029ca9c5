#pragma once

// What every camera identity read from EXIF must be, whatever the bytes: four
// names of at most 40 characters, their separators and "%.1f mm", printable
// ASCII only (it is written into logs and summary.json).

#include <string>

inline bool PlausibleCameraIdentity(const std::string& identity) {
  if (identity.size() > 4 * 41 + 32) return false;
  for (const char c : identity) {
    if (c < 0x20 || c >= 0x7F) return false;
  }
  return true;
}
