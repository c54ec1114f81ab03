// read_cad_file and its checks. The conversion itself runs in the OpenCASCADE module
// (io/occt/, loaded on the first import: occt_module.hpp), in a child process by default
// (cad_isolation.hpp).
#include "nurbsreg/io/cad_import.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string_view>

#include "cad_isolation.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "occt_module.hpp"
#include "text_io.hpp"

namespace nurbsreg::io {

// OCCT's data-exchange session (Interface_Static parameters, the shared XSControl
// controllers) is global state: one import at a time.
std::mutex& cad_detail::occt_mutex() {
  static std::mutex m;
  return m;
}

namespace {

// OCCT happily "reads" a missing file with RetVoid; say what is really wrong.
void check_readable(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(path, "cannot open: not a readable file");
  if (std::filesystem::file_size(path, ec) == 0) throw InputError(path, "the file is empty");
}

// An IGES file ends with its Terminate section (one record with 'T' in column 73). OCCT reads a
// cut-off file without complaint and returns the entities before the cut; say it instead.
void check_iges_complete(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  const std::streamoff tail = std::min<std::streamoff>(size, 400);
  std::string text(static_cast<std::size_t>(tail), '\0');
  in.seekg(size - tail);
  in.read(text.data(), tail);
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back())))
    text.pop_back();
  const std::size_t start = text.find_last_of('\n') + 1;  // npos + 1 == 0
  const std::string last = text.substr(start);
  if (last.size() < 73 || last[72] != 'T') {
    throw InputError(path,
                     "truncated or not an IGES file: the last record is not the Terminate "
                     "section (a 'T' record)");
  }
}

}  // namespace

namespace cad_detail {

engine::Model import_in_process(const std::string& path, CadImportReport* report, bool take_lock) {
  const std::string ext = text_detail::lower_extension(path);
  const bool step = ext == ".step" || ext == ".stp";
  if (!step && ext != ".iges" && ext != ".igs") {
    throw InputError(path, "not a CAD file: expected a .step, .stp, .iges or .igs file");
  }
  if (!step) check_iges_complete(path);
  const OcctImportFunction import = occt_import_function();
  CadImportReport local;
  engine::Model model;
  std::string error;
  OcctImportCall call;
  call.path = &path;
  call.step = step;
  call.report = report != nullptr ? report : &local;
  call.model = &model;
  call.error = &error;
  {
    std::unique_lock<std::mutex> lock(occt_mutex(), std::defer_lock);
    if (take_lock) lock.lock();
    import(&call);
  }
  switch (call.status) {
    case OcctImportCall::kOk:
      return model;
    case OcctImportCall::kInputError:
      throw InputError(path, error);
    case OcctImportCall::kOutOfMemory:
      throw std::bad_alloc();
    case OcctImportCall::kFailure:
      break;
  }
  throw std::runtime_error(path + ": " + error);
}

}  // namespace cad_detail

engine::Model read_cad_file(const std::string& path, CadImportReport* report) {
  const std::string ext = text_detail::lower_extension(path);
  if (ext != ".step" && ext != ".stp" && ext != ".iges" && ext != ".igs") {
    throw InputError(path, "not a CAD file: expected a .step, .stp, .iges or .igs file");
  }
  check_readable(path);
  const char* in_process = std::getenv("NURBSREG_CAD_IN_PROCESS");
  if (in_process != nullptr && std::string_view(in_process) == "1") {
    engine::Model model = cad_detail::import_in_process(path, report);
    // The same load-time checks as the isolated path (which reads the model back as JSON).
    return parse_model(model_to_json(model), path);
  }
  return cad_detail::import_isolated(path, report);
}

engine::Model read_step(const std::string& path, CadImportReport* report) {
  const std::string ext = text_detail::lower_extension(path);
  if (ext != ".step" && ext != ".stp") throw InputError(path, "not a STEP file (.step, .stp)");
  return read_cad_file(path, report);
}

engine::Model read_iges(const std::string& path, CadImportReport* report) {
  const std::string ext = text_detail::lower_extension(path);
  if (ext != ".iges" && ext != ".igs") throw InputError(path, "not an IGES file (.iges, .igs)");
  return read_cad_file(path, report);
}

}  // namespace nurbsreg::io
