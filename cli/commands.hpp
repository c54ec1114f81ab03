#pragma once
// The nurbsreg sub-commands. Each add_*_command registers one sub-command on the app; its
// callback does the work and reports failure by throwing (see main.cpp for the mapping to the
// contract's exit codes). To add a sub-command: a new cli/<name>_command.cpp and one line in
// main.cpp.

#include <CLI/CLI.hpp>

namespace nurbsreg::cli {

void add_info_command(CLI::App& app);
void add_project_command(CLI::App& app);
void add_synth_command(CLI::App& app);
void add_align_command(CLI::App& app);
void add_modify_command(CLI::App& app);
void add_batch_command(CLI::App& app);
void add_inspect_command(CLI::App& app);
void add_serve_command(CLI::App& app);
void add_convert_command(CLI::App& app);

}  // namespace nurbsreg::cli
