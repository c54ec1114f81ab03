// `nurbsreg info --model M`: what a model holds (CONTRACT.md §1).

#include <iostream>

#include "commands.hpp"
#include "common.hpp"
#include "nurbsreg/io/model_summary.hpp"

namespace nurbsreg::cli {

void add_info_command(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("info", "Surfaces, curves, degrees, Bézier patch count, bounding box");
  auto model = std::make_shared<std::string>();
  auto as_json = std::make_shared<bool>(false);
  cmd->add_option("--model", *model, "Model file (.json, .step/.stp, .iges/.igs)")->required();
  cmd->add_flag("--json", *as_json, "Machine-readable JSON on stdout");
  cmd->callback([model, as_json] {
    const io::ModelSummary summary = io::summarize_model(load_model_file(*model));
    std::cout << (*as_json ? io::model_summary_to_json(summary)
                           : io::format_model_summary(summary, *model));
  });
}

}  // namespace nurbsreg::cli
