// `nurbsreg convert part.step part.json`: a CAD file's converted model as the project's JSON
// model, so that later runs load it without OpenCASCADE (the model cache does the same
// transparently; this is the explicit, portable form).

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "commands.hpp"
#include "common.hpp"
#include "nurbsreg/io/model_json.hpp"

namespace nurbsreg::cli {

void add_convert_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "convert", "Convert a model file (STEP, IGES, JSON) to the JSON model format");
  auto in = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  cmd->add_option("input", *in, "Model file (.json, .step/.stp, .iges/.igs)")->required();
  cmd->add_option("output", *out, "The JSON model to write (.json)")->required();
  cmd->callback([in, out] {
    std::string ext = std::filesystem::path(*out).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext != ".json") throw UsageError("convert: the output must be a .json file: " + *out);
    const Stopwatch clock;
    const engine::Model model = load_model_file(*in);
    io::write_model(*out, model);
    spdlog::info("{}: {} surfaces, {} curves, {} skipped faces written to {} ({:.2f} s)", *in,
                 model.surfaces.size(), model.curves.size(), model.skipped_faces.size(), *out,
                 clock.seconds());
  });
}

}  // namespace nurbsreg::cli
