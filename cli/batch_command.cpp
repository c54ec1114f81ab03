// `nurbsreg batch`: many frames of the same part through one prepared model (README "Batch
// jobs").
//
// Design:
//  - The model is loaded and prepared once (PreparedModel is immutable and shared); every frame
//    in flight borrows a Worker (Projector, or registration::Aligner) from a pool,
//    so the per-thread scratch of those objects is reused over frames.
//  - A tbb::parallel_pipeline of four filters: pick the next frame (serial, in order) -> read
//    (parallel) -> align or project and write (parallel) -> record (serial, in order). At most
//    `in_flight` frames are alive at once, so memory is bounded whatever the number of files,
//    and reading frame k+1 overlaps the computation of frame k.
//  - A frame's outputs are the files the single `align` / `project` commands write (the same
//    code, cli/frame_jobs.cpp), each written atomically, then a small `<stem>.done.csv`
//    marker holding its summary row, written last. A frame is complete iff its marker and all
//    its outputs exist; `--resume` skips complete frames and rebuilds their rows from the
//    markers. A failure anywhere in a frame removes that frame's outputs, so nothing of a
//    failed frame looks complete.
//  - SIGINT / SIGTERM (Ctrl-C, Slurm or Kubernetes stopping the job) stop taking new frames;
//    frames in flight finish, the summary is written with the rest marked `pending`, and the
//    command exits 1, ready for `--resume`.

#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "commands.hpp"
#include "common.hpp"
#include "frame_jobs.hpp"
#include "nurbsreg/io/atomic_file.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/pose.hpp"

namespace nurbsreg::cli {
namespace {

namespace fs = std::filesystem;

struct BatchArgs {
  std::string model;
  std::string scans;
  std::string list;
  std::string out;
  std::string mode = "align";
  std::string init;
  std::string shard;
  std::string target = "surfaces";
  std::string format = "csv";
  IcpArgs icp;
  GlobalArgs global;
  int threads = 0;
  int in_flight = 0;
  bool resume = false;
  double summary_interval = 30.0;
};

// Point-cloud extensions taken from a --scans directory (CONTRACT §2 "Point clouds").
bool is_point_file(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".pcd" || ext == ".ply" || ext == ".xyz" || ext == ".txt" || ext == ".csv";
}

// Regular point files of `dir` (not hidden: atomic writers' temporaries start with '.'), sorted
// by name so every machine of a sharded job sees the same order.
std::vector<std::string> list_directory(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw io::InputError(dir, "--scans: not a directory");
  std::vector<fs::path> files;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir, ec)) {
    const fs::path& p = entry.path();
    if (!entry.is_regular_file() || p.filename().string().starts_with(".")) continue;
    if (is_point_file(p)) files.push_back(p);
  }
  if (ec) throw io::InputError(dir, "cannot list the directory: " + ec.message());
  std::sort(files.begin(), files.end(),
            [](const fs::path& a, const fs::path& b) { return a.filename() < b.filename(); });
  std::vector<std::string> out;
  for (const fs::path& p : files)
    out.push_back(p.string());
  return out;
}

// One path per line; blank lines and `#` comments ignored; relative paths are relative to the
// list file's directory (so a list travels with its data).
std::vector<std::string> read_list(const std::string& list) {
  std::ifstream in(list);
  if (!in) throw io::InputError(list, "cannot open the list file");
  const fs::path base = fs::path(list).parent_path();
  std::vector<std::string> out;
  std::string line;
  while (std::getline(in, line)) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const auto last = line.find_last_not_of(" \t\r");
    const fs::path p(line.substr(first, last - first + 1));
    out.push_back(p.is_absolute() ? p.string() : (base / p).string());
  }
  return out;
}

struct Shard {
  std::size_t index = 0;
  std::size_t count = 1;
};

Shard parse_shard(const std::string& text) {
  Shard s;
  if (text.empty()) return s;
  const auto slash = text.find('/');
  auto number = [&](std::string_view part, std::size_t& value) {
    if (part.empty() || part.find_first_not_of("0123456789") != std::string_view::npos ||
        part.size() > 9) {
      return false;
    }
    value = std::stoul(std::string(part));
    return true;
  };
  const std::string_view view(text);
  if (slash == std::string::npos || !number(view.substr(0, slash), s.index) ||
      !number(view.substr(slash + 1), s.count) || s.count == 0 || s.index >= s.count) {
    throw UsageError("--shard: expected I/N with 0 <= I < N (e.g. 3/8), got \"" + text + "\"");
  }
  return s;
}

// ---- summary rows -----------------------------------------------------------------------------

constexpr const char* kSummaryHeader =
    "file,points,skipped,status,rms,iterations,pose,seconds,reason";

std::string csv_field(const std::string& text) {
  std::string clean = text;
  std::replace(clean.begin(), clean.end(), '\n', ' ');
  std::replace(clean.begin(), clean.end(), '\r', ' ');
  if (clean.find_first_of(",\"") == std::string::npos) return clean;
  std::string quoted = "\"";
  for (char c : clean) {
    if (c == '"') quoted += '"';
    quoted += c;
  }
  return quoted + "\"";
}

struct Row {
  std::string file;
  std::string status = "pending";  // ok | failed | pending (not reached: interrupted)
  std::size_t points = 0;
  std::size_t skipped = 0;
  std::string rms;         // shortest exact form; project: RMS distance of all points
  std::string iterations;  // align only
  std::string pose;        // align only: 16 numbers, row-major, space-separated
  double seconds = 0.0;
  std::string reason;
  bool resumed = false;

  std::string to_csv() const {
    if (status == "pending") return csv_field(file) + ",,,pending,,,,,";
    return fmt::format("{},{},{},{},{},{},{},{:.6f},{}", csv_field(file), points, skipped, status,
                       rms, iterations, pose, seconds, csv_field(reason));
  }
};

// Splits one CSV line written by Row::to_csv (quoted fields allowed).
std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        fields.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        fields.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  return fields;
}

// The row of a completed frame, from its marker; nothing if the marker is not a complete one.
std::optional<Row> read_marker(const std::string& path) {
  std::ifstream in(path);
  std::string header;
  std::string line;
  if (!in || !std::getline(in, header) || !std::getline(in, line) || header != kSummaryHeader) {
    return std::nullopt;
  }
  const std::vector<std::string> f = split_csv(line);
  if (f.size() != 9 || f[3] != "ok") return std::nullopt;
  Row row;
  try {
    row.file = f[0];
    row.points = std::stoull(f[1]);
    row.skipped = std::stoull(f[2]);
    row.status = f[3];
    row.rms = f[4];
    row.iterations = f[5];
    row.pose = f[6];
    row.seconds = std::stod(f[7]);
    row.reason = f[8];
  } catch (const std::exception&) {
    return std::nullopt;
  }
  return row;
}

void write_summary(const std::string& path, const std::vector<Row>& rows) {
  io::write_atomically(path, [&](std::ostream& out) {
    out << kSummaryHeader << '\n';
    for (const Row& row : rows)
      out << row.to_csv() << '\n';
  });
}

// ---- frames -----------------------------------------------------------------------------------

struct Frame {
  std::string input;
  std::string stem;
  std::vector<std::string> outputs;  // the files align/project write for this frame
  AlignOutputs align;                // align mode
  std::string projection;            // project mode
  std::string marker;                // written last: the frame is complete
};

// Removes a frame's marker, outputs and leftover temporaries of an earlier killed run
// (`.<name>.tmp-<pid>-<n>`, io/atomic_file.hpp). The frame belongs to this shard only, so no
// other live process writes these names.
void clear_frame(const Frame& frame, const fs::path& out_dir) {
  std::error_code ignored;
  fs::remove(frame.marker, ignored);
  for (const std::string& o : frame.outputs)
    fs::remove(o, ignored);
  std::vector<std::string> prefixes;
  for (const std::string& o : frame.outputs)
    prefixes.push_back("." + fs::path(o).filename().string() + ".tmp-");
  prefixes.push_back("." + fs::path(frame.marker).filename().string() + ".tmp-");
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(out_dir, ec)) {
    const std::string name = entry.path().filename().string();
    for (const std::string& prefix : prefixes) {
      if (name.starts_with(prefix)) fs::remove(entry.path(), ignored);
    }
  }
}

bool frame_complete(const Frame& frame) {
  std::error_code ec;
  if (!fs::exists(frame.marker, ec)) return false;
  return std::all_of(frame.outputs.begin(), frame.outputs.end(), [](const std::string& o) {
    std::error_code e;
    return fs::exists(o, e);
  });
}

// Per-frame engine objects, reused over frames: their scratch grows on the first frames and is
// then reused. One frame at a time per Worker.
struct Worker {
  std::unique_ptr<engine::Projector> projector;
  std::unique_ptr<registration::Aligner> aligner;
};

class WorkerPool {
 public:
  WorkerPool(std::size_t size, const engine::PreparedModel& model, bool align, bool global,
             const icp::IcpOptions& options, const registration::RegistrationOptions& reg) {
    // One set of coarse-stage features for all workers: from any pose (`global`) through the
    // features cache, otherwise only the area and keypoints are needed, from the cache when
    // there.
    std::shared_ptr<const registration::ModelFeatures> features;
    if (align) {
      features = global ? load_features(model, reg.global.features)
                        : cached_features(model, reg.global.features);
    }
    for (std::size_t i = 0; i < size; ++i) {
      auto w = std::make_unique<Worker>();
      if (align) {
        w->aligner = std::make_unique<registration::Aligner>(model, options, reg, features);
      } else {
        w->projector = std::make_unique<engine::Projector>(model);
      }
      free_.push_back(std::move(w));
    }
  }
  // The pool holds one Worker per pipeline token, so a frame always finds one free.
  std::unique_ptr<Worker> acquire() {
    std::lock_guard lock(mutex_);
    auto w = std::move(free_.back());
    free_.pop_back();
    return w;
  }
  void release(std::unique_ptr<Worker> w) {
    std::lock_guard lock(mutex_);
    free_.push_back(std::move(w));
  }

 private:
  std::mutex mutex_;
  std::vector<std::unique_ptr<Worker>> free_;
};

std::atomic<bool> g_stop_requested{false};
void request_stop(int) {
  g_stop_requested.store(true);
}

// Installs the stop handler for SIGINT/SIGTERM for its lifetime, restoring the previous ones.
class StopOnSignal {
 public:
  StopOnSignal() {
    g_stop_requested.store(false);
    struct sigaction action {};
    action.sa_handler = request_stop;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &old_int_);
    sigaction(SIGTERM, &action, &old_term_);
  }
  ~StopOnSignal() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  StopOnSignal(const StopOnSignal&) = delete;
  StopOnSignal& operator=(const StopOnSignal&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

std::string pose_field(const Eigen::Matrix4d& T) {
  std::string s;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c)
      s += fmt::format("{}{}", (r || c) ? " " : "", T(r, c));
  }
  return s;
}

// What travels through the pipeline: one frame.
struct Token {
  std::size_t slot = 0;  // index into frames / rows
  io::PointCloud cloud;
  Row row;
  Stopwatch clock;
  bool failed = false;
};

void fail(Token& token, const Frame& frame, const std::string& reason) {
  token.failed = true;
  token.row.status = "failed";
  token.row.reason = reason;
  std::error_code ignored;
  for (const std::string& o : frame.outputs)
    fs::remove(o, ignored);
  fs::remove(frame.marker, ignored);
}

void run_batch(const BatchArgs& args) {
  const Stopwatch total;
  // ---- usage checks first (exit 2), then inputs (exit 3) ----
  if (args.scans.empty() == args.list.empty()) {
    throw UsageError("batch: give exactly one of --scans DIR or --list FILE");
  }
  const bool align = args.mode == "align";
  if (!align && args.mode != "project") {
    throw UsageError("--mode: expected align or project, got \"" + args.mode + "\"");
  }
  if (args.format != "csv" && args.format != "pcd") {
    throw UsageError("--format: expected csv or pcd, got \"" + args.format + "\"");
  }
  const Shard shard = parse_shard(args.shard);
  const engine::ProjectionTarget target = parse_projection_target(args.target);
  const icp::IcpOptions options = icp_options(args.icp);
  const auto threads = limit_threads(args.threads);
  if (args.in_flight < 0) throw UsageError("--in-flight: must be >= 0 (0 = automatic)");
  if (!args.scans.empty() && fs::exists(args.out)) {
    std::error_code ec;
    if (fs::equivalent(args.scans, args.out, ec)) {
      throw UsageError("--out: must differ from --scans (outputs would be taken as inputs)");
    }
  }

  const std::vector<std::string> inputs =
      args.scans.empty() ? read_list(args.list) : list_directory(args.scans);

  // Output names come from the input file names; two inputs with one stem would overwrite
  // each other's outputs (checked over all inputs: shards share the output directory).
  std::map<std::string, std::string> stems;
  for (const std::string& input : inputs) {
    const std::string stem = fs::path(input).stem().string();
    const auto [it, inserted] = stems.emplace(stem, input);
    if (!inserted) {
      throw UsageError("batch: " + it->second + " and " + input +
                       " would write the same outputs (same name " + stem + ")");
    }
  }

  const fs::path out_dir(args.out);
  std::vector<Frame> frames;
  for (std::size_t k = shard.index; k < inputs.size(); k += shard.count) {
    Frame f;
    f.input = inputs[k];
    f.stem = fs::path(f.input).stem().string();
    const std::string base = (out_dir / f.stem).string();
    if (align) {
      f.align = {base + ".pose.txt", base + ".aligned.pcd", base + ".report.json"};
      f.outputs = {f.align.pose, f.align.aligned, f.align.report};
    } else {
      f.projection = base + ".projection." + args.format;
      f.outputs = {f.projection};
    }
    f.marker = base + ".done.csv";
    frames.push_back(std::move(f));
  }
  const std::string summary_path =
      (out_dir / (shard.count == 1
                      ? std::string("summary.csv")
                      : fmt::format("summary.shard-{}-of-{}.csv", shard.index, shard.count)))
          .string();

  const registration::AlignRequest request = align_request(args.init, args.global);

  const Stopwatch prepare;
  engine::Model model = load_model_file(args.model);
  if (align && model.surfaces.empty()) {
    throw UsageError(args.model + ": align needs a model with surfaces");
  }
  const engine::PreparedModel prepared(std::move(model));
  if (!align) check_projection_target(prepared.model(), target, args.model);
  spdlog::info("{}: {} Bézier patches prepared in {:.3f} s (shared by all frames)", args.model,
               prepared.patch_count(), prepare.seconds());

  {
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec || !fs::is_directory(out_dir)) {
      throw io::OutputError(args.out, "cannot create the output directory");
    }
  }
  // ---- rows: resumed frames are filled from their markers ----
  std::vector<Row> rows(frames.size());
  std::vector<std::size_t> todo;
  std::size_t resumed = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    rows[i].file = frames[i].input;
    if (args.resume && frame_complete(frames[i])) {
      if (auto row = read_marker(frames[i].marker); row && row->file == frames[i].input) {
        rows[i] = *row;
        rows[i].resumed = true;
        ++resumed;
        continue;
      }
    }
    todo.push_back(i);
  }
  spdlog::info("batch: {} inputs, shard {}/{}: {} frames, {} already complete, {} to do",
               inputs.size(), shard.index, shard.count, frames.size(), resumed, todo.size());

  const std::size_t parallelism =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  // One frame per thread computing plus one being read, capped: within a frame the projection
  // is itself parallel, so more frames in flight only cost memory.
  const std::size_t in_flight = args.in_flight > 0 ? static_cast<std::size_t>(args.in_flight)
                                                   : std::min<std::size_t>(parallelism, 4) + 1;
  // A batch resumed with nothing left to do builds no features.
  WorkerPool pool(in_flight, prepared, align, request.runs_global() && !todo.empty(), options,
                  registration_options(args.global));

  StopOnSignal stop_on_signal;
  std::size_t next = 0;
  std::size_t done = 0;
  std::size_t failed = 0;
  std::uint64_t points_done = 0;
  const Stopwatch run;
  double last_progress = 0.0;
  double last_summary = 0.0;

  tbb::parallel_pipeline(
      in_flight,
      tbb::make_filter<
          void, Token*>(tbb::filter_mode::serial_in_order, [&](tbb::flow_control& fc) -> Token* {
        if (next >= todo.size() || g_stop_requested.load()) {
          fc.stop();
          return nullptr;
        }
        auto* token = new Token;
        token->slot = todo[next++];
        token->row.file = frames[token->slot].input;
        return token;
      }) & tbb::make_filter<Token*, Token*>(tbb::filter_mode::parallel, [&](Token* token) {
        const Frame& frame = frames[token->slot];
        token->clock = Stopwatch();
        try {
          // The old marker goes first: from here until the new one is written the
          // frame is incomplete, whatever outputs exist.
          clear_frame(frame, out_dir);
          // An inspection frame without points is a fault of the scanner or the transfer:
          // read_scan says so, as for the single commands.
          token->cloud = io::read_scan(frame.input);
          token->row.points = token->cloud.size();
          token->row.skipped = token->cloud.skipped_nonfinite;
        } catch (const std::exception& e) {
          fail(*token, frame, e.what());
        }
        return token;
      }) & tbb::make_filter<Token*, Token*>(tbb::filter_mode::parallel, [&](Token* token) {
        if (token->failed) return token;
        const Frame& frame = frames[token->slot];
        std::unique_ptr<Worker> worker = pool.acquire();
        try {
          // Isolation: while this frame waits for its own parallel loops, the thread
          // does not start another frame's work on top of it (bounded stack, and each
          // Worker's per-thread scratch is used by one frame at a time).
          tbb::this_task_arena::isolate([&] {
            const registration::ScanSize sizes = scan_size(token->cloud, prepared);
            if (align) {
              const registration::AlignmentResult r =
                  align_frame(*worker->aligner, token->cloud, request);
              // A failed frame keeps no output (fail() removes them); its reason is in the
              // summary.
              if (r.failure) throw std::runtime_error(*r.failure);
              warn_if_unconverged(token->row.file, r.icp, args.icp);
              warn_about_fit(token->row.file, r);
              write_align_outputs(r, *worker->aligner, token->cloud, args.icp, frame.align,
                                  token->clock);
              token->row.rms = fmt::format("{}", r.icp.rms);
              token->row.iterations = std::to_string(r.icp.iterations);
              token->row.pose = pose_field(r.icp.T_model_scan.matrix());
            } else {
              const ProjectFrameResult r =
                  project_frame(*worker->projector, token->cloud, target, frame.projection, false);
              token->row.rms = fmt::format("{}", r.rms_distance);
              if (r.far_note) spdlog::warn("{}: {}", token->row.file, *r.far_note);
            }
            if (const auto note = sizes.warning()) spdlog::warn("{}: {}", token->row.file, *note);
          });
          token->row.status = "ok";
          token->row.seconds = token->clock.seconds();
          const std::string row = token->row.to_csv();
          io::write_atomically(frame.marker, [&](std::ostream& out) {
            out << kSummaryHeader << '\n' << row << '\n';
          });
        } catch (const std::exception& e) {
          fail(*token, frame, e.what());
        }
        pool.release(std::move(worker));
        token->cloud = io::PointCloud{};  // free the frame's memory early
        return token;
      }) & tbb::make_filter<Token*, void>(tbb::filter_mode::serial_in_order, [&](Token* raw) {
        const std::unique_ptr<Token> token(raw);
        if (token->failed) token->row.seconds = token->clock.seconds();
        rows[token->slot] = token->row;
        ++done;
        if (token->failed) {
          ++failed;
          spdlog::warn("frame {} failed: {}", token->row.file, token->row.reason);
        } else {
          points_done += token->row.points;
        }
        const double elapsed = run.seconds();
        if (elapsed - last_progress >= 1.0 || done == todo.size()) {
          last_progress = elapsed;
          const double per_frame = elapsed / static_cast<double>(done);
          spdlog::info(
              "batch: {}/{} frames ({} failed), {:.0f} points/s, {:.2f} frames/s, "
              "{:.0f} s left",
              done + resumed, frames.size(), failed, static_cast<double>(points_done) / elapsed,
              static_cast<double>(done) / elapsed,
              per_frame * static_cast<double>(todo.size() - done));
        }
        if (args.summary_interval > 0 && elapsed - last_summary >= args.summary_interval) {
          last_summary = elapsed;
          write_summary(summary_path, rows);
        }
      }));
  const double seconds = run.seconds();
  write_summary(summary_path, rows);

  const std::size_t ok =
      std::count_if(rows.begin(), rows.end(), [](const Row& r) { return r.status == "ok"; });
  std::cout << fmt::format(
      "batch: {} frames ok ({} resumed), {} failed, {} pending, of {}; {:.0f} points/s, {:.3f} "
      "frames/s over the {} frames processed in {:.2f} s ({:.2f} s total); summary {}\n",
      ok, resumed, failed, frames.size() - ok - failed, frames.size(),
      seconds > 0 ? static_cast<double>(points_done) / seconds : 0.0,
      seconds > 0 ? static_cast<double>(done) / seconds : 0.0, done, seconds, total.seconds(),
      summary_path);
  if (g_stop_requested.load() && done + resumed < frames.size()) {
    throw std::runtime_error(
        fmt::format("batch interrupted: {} of {} frames not started; rerun with --resume to finish",
                    frames.size() - done - resumed, frames.size()));
  }
  if (failed > 0) {
    throw FramesFailed(
        fmt::format("{} of {} frames failed (reasons in {})", failed, frames.size(), summary_path));
  }
}

}  // namespace

void add_batch_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "batch", "Align or project many frames with one prepared model (exit 4: some frames failed)");
  auto args = std::make_shared<BatchArgs>();
  cmd->add_option("--model", args->model, "Model file (.json, .step/.stp, .iges/.igs)")->required();
  cmd->add_option("--scans", args->scans,
                  "Directory of frames (.pcd .ply .xyz .txt .csv, sorted by name)");
  cmd->add_option("--list", args->list,
                  "File listing frames, one path a line (relative to the list's directory)");
  cmd->add_option("--out", args->out, "Output directory (created if missing)")->required();
  cmd->add_option("--mode", args->mode, "align (default): pose + deviations; project: deviations")
      ->check(CLI::IsMember({"align", "project"}));
  cmd->add_option("--init", args->init,
                  "align: initial pose T0 for every frame (none or \"auto\": global alignment)");
  cmd->add_option("--target", args->target, "project: onto the model's surfaces or curves")
      ->check(CLI::IsMember({"surfaces", "curves"}));
  cmd->add_option("--format", args->format, "project: results as csv (default) or pcd")
      ->check(CLI::IsMember({"csv", "pcd"}));
  add_icp_options(*cmd, args->icp);
  add_global_options(*cmd, args->global);
  cmd->add_option("--threads", args->threads, "Worker threads (0 = all hardware threads)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--in-flight", args->in_flight,
                  "Frames in memory at once (0 = min(threads, 4) + 1)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--shard", args->shard,
                  "I/N: process inputs k with k % N == I (sorted order), 0 <= I < N");
  cmd->add_flag("--resume", args->resume, "Skip frames whose outputs are complete");
  cmd->add_option("--summary-every", args->summary_interval,
                  "Rewrite the summary CSV every this many seconds during the run (0: at the end)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([args] { run_batch(*args); });
}

}  // namespace nurbsreg::cli
