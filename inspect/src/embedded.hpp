#pragma once
// The files embedded at build time (inspect/CMakeLists.txt, cmake/embed_file.cmake).

#include <string_view>

namespace nurbsreg::inspect::embedded {

std::string_view three_module_js();  // three.js's minified ES module (npm, pinned)
std::string_view viewer_js();        // inspect/web/viewer.js
std::string_view report_css();       // inspect/web/report.css

}  // namespace nurbsreg::inspect::embedded
