// nurbsreg: exact projection of scans onto NURBS models and scan-to-CAD alignment.
// Thin: parse, call the library, report. Exit status per CONTRACT.md: 0 success, 2 usage
// error, 3 bad input, 1 any other failure, with exactly one `error: ...` line on stderr; and
// 4 for `batch` when some frames failed while the others were processed (README "Batch jobs").

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>
#include <new>

#include "commands.hpp"
#include "common.hpp"
#include "nurbsreg/io/errors.hpp"

namespace {

constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;
constexpr int kExitBadInput = 3;
constexpr int kExitFramesFailed = 4;  // batch: some frames failed, the others are done

void set_up_logging(bool verbose, bool quiet) {
  auto logger = spdlog::stderr_color_mt("nurbsreg");
  logger->set_pattern("[%H:%M:%S.%e] %^%l%$ %v");
  logger->set_level(quiet ? spdlog::level::warn
                          : (verbose ? spdlog::level::debug : spdlog::level::info));
  spdlog::set_default_logger(logger);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"nurbsreg: exact closest points on NURBS models and scan-to-CAD alignment"};
  app.require_subcommand(1);
  bool verbose = false;
  bool quiet = false;
  app.add_flag("-v,--verbose", verbose, "More log output (debug level) on stderr");
  app.add_flag("-q,--quiet", quiet, "Only warnings and errors on stderr");
  bool no_cache = false;
  app.add_flag("--no-cache", no_cache,
               "Use neither cache: convert STEP/IGES files and build the model features again "
               "(also: NURBSREG_NO_CACHE=1)");
  app.parse_complete_callback([&] {
    set_up_logging(verbose, quiet);
    if (no_cache) nurbsreg::cli::disable_model_cache();
  });

  nurbsreg::cli::add_info_command(app);
  nurbsreg::cli::add_project_command(app);
  nurbsreg::cli::add_synth_command(app);
  nurbsreg::cli::add_align_command(app);
  nurbsreg::cli::add_modify_command(app);
  nurbsreg::cli::add_batch_command(app);
  nurbsreg::cli::add_inspect_command(app);
  nurbsreg::cli::add_serve_command(app);
  nurbsreg::cli::add_convert_command(app);

  try {
    app.parse(argc, argv);
    return 0;
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);  // prints help, or the message and a hint
    return code == 0 ? 0 : kExitUsage;
  } catch (const nurbsreg::cli::UsageError& e) {
    std::cerr << "error: " << e.what() << "\nRun with --help for more information.\n";
    return kExitUsage;
  } catch (const nurbsreg::cli::FramesFailed& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitFramesFailed;
  } catch (const nurbsreg::io::InputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::bad_alloc&) {
    std::cerr << "error: out of memory\n";
    return kExitFailure;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitFailure;
  } catch (...) {
    std::cerr << "error: unknown failure\n";
    return kExitFailure;
  }
}
