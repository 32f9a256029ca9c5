#pragma once

// The page of the live view (io/view/www/), compiled in by
// io/view/CMakeLists.txt.

namespace flysfm {

extern const char* const kViewIndexHtml;
extern const char* const kViewJs;

}  // namespace flysfm
