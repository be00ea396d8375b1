#include "batch.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "traverse/core/error.h"
#include "traverse/eval/metrics.h"
#include "traverse/io/atomic_file.h"

extern char** environ;

namespace traverse::app {
namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

namespace {

std::string shortest(double v) {
  char buf[32];
  return std::string(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
}

/// The folder name a log's outputs go to: its directory's own name.
std::string logName(const std::string& log_dir) {
  const fs::path p = fs::absolute(log_dir).lexically_normal();
  std::string name = p.filename().string();
  if (name.empty()) name = p.parent_path().filename().string();  // "logs/a/" → "a"
  return name.empty() ? log_dir : name;
}

/// The newest modification time of the files a run reads: everything under the log directory
/// and the calibration overlay. Unreadable entries count as "now" (never up to date).
fs::file_time_type newestInput(const std::string& log_dir, const std::string& calibration) {
  fs::file_time_type newest = fs::file_time_type::min();
  std::error_code ec;
  auto consider = [&](const fs::path& p) {
    const auto t = fs::last_write_time(p, ec);
    newest = ec ? fs::file_time_type::max() : std::max(newest, t);
  };
  if (!fs::is_directory(log_dir, ec)) return fs::file_time_type::max();
  consider(log_dir);
  for (auto it = fs::recursive_directory_iterator(log_dir, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
    consider(it->path());
  if (ec) return fs::file_time_type::max();
  if (!calibration.empty()) consider(calibration);
  return newest;
}

Json readJsonFile(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string(), 0, "cannot open");
  try {
    return Json::parse(in);
  } catch (const Json::parse_error& e) {
    throw InputError(file.string(), 0, std::string("not JSON: ") + e.what());
  }
}

/// Outputs newer than every input, made by a run that ended well with the same arguments.
bool upToDate(const fs::path& out, const std::string& log_dir, const Json& arguments,
              const std::string& calibration, bool smooth) {
  std::error_code ec;
  const fs::path status = out / "status.json";
  for (const char* f : {"status.json", "metrics.json", "segments.csv", "dr.csv", "ekf.csv"}) {
    if (!fs::exists(out / f, ec)) return false;
  }
  if (smooth && !fs::exists(out / "smoothed.csv", ec)) return false;
  try {
    const Json s = readJsonFile(status);
    if (s.value("status", "") != "ok" || s.value("arguments", Json()) != arguments) return false;
  } catch (const InputError&) {
    return false;
  }
  const auto written = fs::last_write_time(status, ec);
  return !ec && written > newestInput(log_dir, calibration);
}

/// The last line of a file that is not a warning: the child's error line.
std::string errorLine(const fs::path& stderr_file) {
  std::ifstream in(stderr_file);
  std::string line, last;
  while (std::getline(in, line)) {
    if (!line.empty() && line.rfind("warning:", 0) != 0) last = line;
  }
  return last;
}

struct Job {
  std::string log_dir, name;
  fs::path out;
  pid_t pid = -1;
  std::chrono::steady_clock::time_point started;
};

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (const char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string csvNumber(double v) {
  return std::isfinite(v) ? shortest(v) : std::string();
}

}  // namespace

std::vector<std::string> pipelineArguments(const PipelineOptions& o, bool smooth) {
  std::vector<std::string> a;
  if (o.skip_bad_rows) a.push_back("--skip-bad-rows");
  if (!o.calibration.empty())
    a.insert(a.end(), {"--calibration", fs::absolute(o.calibration).lexically_normal().string()});
  a.push_back("--initial-position");
  for (const double x : o.initial_position) a.push_back(shortest(x));
  a.insert(a.end(), {"--attitude-model", o.attitude_model});
  if (o.velocity_model != "auto") a.insert(a.end(), {"--velocity-model", o.velocity_model});
  if (o.no_sun) a.push_back("--no-sun");
  if (o.no_slip) a.push_back("--no-slip");
  if (o.no_gating) a.push_back("--no-gating");
  if (o.pitch_projection) a.push_back("--pitch-projection");
  if (o.no_clock_align) a.push_back("--no-clock-align");
  if (o.no_noise_check) a.push_back("--no-noise-check");
  if (o.no_rts) a.push_back("--no-rts");
  if (o.joints_clock_offset_s)
    a.insert(a.end(), {"--joints-clock-offset", shortest(*o.joints_clock_offset_s)});
  if (!smooth) return a;
  a.insert(a.end(), {"--node-period", shortest(o.node_period_s), "--bias-model", o.bias_model});
  if (!o.loss.empty()) a.insert(a.end(), {"--loss", o.loss});
  if (o.loss_scale > 0.0) a.insert(a.end(), {"--loss-scale", shortest(o.loss_scale)});
  a.insert(a.end(), {"--contact-loss-scale", shortest(o.contact_loss_scale), "--max-iterations",
                     std::to_string(o.max_iterations)});
  if (o.no_covariance) a.push_back("--no-covariance");
  if (o.solver_report) a.push_back("--solver-report");
  if (o.no_report) a.push_back("--no-report");
  return a;  // --threads is left out: it changes the time a run takes, not its results
}

int runBatch(const std::vector<std::string>& log_dirs, const PipelineOptions& options,
             const BatchOptions& batch, const GlobalOptions& global, bool smooth) {
  const fs::path out_dir = options.out_dir;
  std::vector<Job> todo;
  std::map<std::string, std::string> seen;
  for (const std::string& dir : log_dirs) {
    Job j{dir, logName(dir), {}, -1, {}};
    if (const auto [it, fresh] = seen.emplace(j.name, dir); !fresh)
      throw InputError(dir, 0,
                       "has the same directory name as " + it->second + ": both would write " +
                           (out_dir / j.name).string());
    j.out = out_dir / j.name;
    todo.push_back(std::move(j));
  }
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  const int jobs = batch.jobs > 0 ? batch.jobs : static_cast<int>(cores);
  const std::vector<std::string> args = pipelineArguments(options, smooth);
  const Json arguments = args;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw std::runtime_error("cannot find the traverse executable (/proc/self/exe)");
  fs::create_directories(out_dir);

  const bool bar = !global.quiet && isatty(STDERR_FILENO);
  const auto t_begin = std::chrono::steady_clock::now();
  std::vector<Job> running;
  size_t next = 0, done = 0;
  int refused = 0, failed = 0, skipped = 0;
  auto clearBar = [&] {
    if (bar) std::cerr << "\r\033[K" << std::flush;
  };
  auto drawBar = [&] {
    if (!bar) return;
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_begin).count();
    std::string names;
    for (const Job& j : running) names += (names.empty() ? "" : ", ") + j.name;
    const int width = 24;
    const int filled = static_cast<int>(width * done / todo.size());
    char head[96];
    std::snprintf(head, sizeof head, "[%s%s] %zu/%zu logs, %.0f s",
                  std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(), done,
                  todo.size(), s);
    std::string line = std::string(head) + (names.empty() ? "" : "; running: " + names);
    if (line.size() > 110) line = line.substr(0, 107) + "...";
    std::cerr << "\r\033[K" << line << std::flush;
  };
  auto finish = [&](Job& j, int status) {
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - j.started).count();
    std::string state = "ok", message;
    int code = 0;
    if (WIFEXITED(status)) {
      code = WEXITSTATUS(status);
      if (code == 2) state = "refused";
      if (code != 0 && code != 2) state = "failed";
    } else {
      state = "failed", code = -1;
      message = "killed by signal " + std::to_string(WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    }
    if (state != "ok" && message.empty()) message = errorLine(j.out / "stderr.txt");
    Json s = Json::object();
    s["log"] = fs::absolute(j.log_dir).lexically_normal().string();
    s["command"] = smooth ? options.command_name : "filter";
    s["status"] = state;
    s["exit_code"] = code;
    s["message"] = message;
    s["seconds"] = seconds;
    s["arguments"] = arguments;
    io::writeFileAtomically(j.out / "status.json",
                            s.dump(2, ' ', false, Json::error_handler_t::replace) + "\n");
    ++done;
    clearBar();
    if (state == "refused") ++refused;
    if (state == "failed") ++failed;
    if (state != "ok")
      std::cerr << "traverse: " << j.name << ": " << state << ": " << message << "\n";
    else if (!global.quiet)
      std::printf("%s: ok (%.1f s)\n", j.name.c_str(), seconds), std::fflush(stdout);
    drawBar();
  };
  auto spawn = [&](Job& j) {
    fs::create_directories(j.out);
    std::vector<std::string> argv_s = {exe.string(),
                                       smooth ? options.command_name : std::string("filter"),
                                       j.log_dir, "-o", j.out.string()};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    if (smooth) {  // the cores shared out between the logs running at once
      const int threads =
          options.threads > 0 ? options.threads : std::max(1, static_cast<int>(cores) / jobs);
      argv_s.insert(argv_s.end(), {"--threads", std::to_string(threads)});
    }
    std::vector<char*> argv;
    for (std::string& s : argv_s) argv.push_back(s.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    const std::string out_txt = (j.out / "stdout.txt").string(),
                      err_txt = (j.out / "stderr.txt").string();
    posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, out_txt.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, err_txt.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    j.started = std::chrono::steady_clock::now();
    const int rc = posix_spawn(&j.pid, exe.c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) throw std::runtime_error("cannot start " + exe.string() + " for " + j.log_dir);
  };

  drawBar();
  while (next < todo.size() || !running.empty()) {
    while (next < todo.size() && static_cast<int>(running.size()) < jobs) {
      Job& j = todo[next++];
      if (!batch.force && upToDate(j.out, j.log_dir, arguments, options.calibration, smooth)) {
        ++done, ++skipped;
        clearBar();
        if (!global.quiet)
          std::printf("%s: skipped, outputs up to date (--force runs it)\n", j.name.c_str()),
              std::fflush(stdout);
        drawBar();
        continue;
      }
      spawn(j);
      running.push_back(j);
      drawBar();
    }
    if (running.empty()) break;
    int status = 0;
    const pid_t pid = waitpid(-1, &status, bar ? WNOHANG : 0);
    if (pid == 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      drawBar();
      continue;
    }
    if (pid < 0) throw std::runtime_error("waitpid failed");
    const auto it =
        std::find_if(running.begin(), running.end(), [pid](const Job& j) { return j.pid == pid; });
    if (it == running.end()) continue;
    finish(*it, status);
    running.erase(it);
  }
  clearBar();
  writeSummary(out_dir);
  if (!global.quiet) {
    std::printf("%zu logs: %zu ok (%d skipped), %d refused, %d failed; wrote %s\n", todo.size(),
                todo.size() - refused - failed, skipped, refused, failed,
                (out_dir / "summary.csv").string().c_str());
  }
  return refused > 0 ? 2 : failed > 0 ? 1 : 0;
}

int writeSummary(const fs::path& out_dir) {
  static const std::vector<std::string> kEstimators = {"dr", "ekf", "rts", "smoother"};
  static const std::vector<std::string> kMetrics = {"ate_posyaw_m", "final_position_error_m",
                                                    "position_rmse_over_sigma",
                                                    "nees_position_mean", "yaw_rmse_deg"};
  std::vector<fs::path> folders;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(out_dir, ec)) {
    if (entry.is_directory() && fs::exists(entry.path() / "status.json"))
      folders.push_back(entry.path());
  }
  if (ec) throw InputError(out_dir.string(), 0, "cannot read the directory: " + ec.message());
  std::sort(folders.begin(), folders.end());
  std::ostringstream csv;
  csv << "log,status,message,seconds,duration_s,path_length_m,estimated_path_length_m,segments,"
         "smoother_fallbacks,slip_updates_gated_pct,diagnostics";
  for (const std::string& e : kEstimators)
    for (const std::string& m : kMetrics) csv << "," << e << "_" << m;
  csv << "\n";
  for (const fs::path& folder : folders) {
    const fs::path status_file = folder / "status.json";
    const Json s = readJsonFile(status_file);
    if (!s.is_object() || !s.contains("status") || !s["status"].is_string())
      throw InputError(status_file.string(), 0, "no \"status\"");
    const std::string state = s["status"].get<std::string>();
    const double seconds =
        s.contains("seconds") && s["seconds"].is_number() ? s["seconds"].get<double>() : NAN;
    csv << csvField(folder.filename().string()) << "," << state << ","
        << csvField(s.value("message", "")) << "," << csvNumber(seconds);
    std::optional<eval::MetricsReport> m;
    if (state == "ok") m = eval::readMetricsJson(folder / "metrics.json");
    const eval::RunSummary run = m && m->run ? *m->run : eval::RunSummary{NAN, NAN, 0, 0, 0, NAN};
    const bool has_run = m && m->run;
    long findings = 0;
    if (m && m->diagnostics) findings = static_cast<long>(m->diagnostics->findings.size());
    csv << "," << csvNumber(run.duration_s) << ","
        << (m && m->evaluated ? csvNumber(m->path_length_m) : std::string()) << ","
        << csvNumber(run.estimated_path_length_m) << ","
        << (has_run ? std::to_string(run.segments) : std::string()) << ","
        << (has_run ? std::to_string(run.smoother_fallbacks) : std::string()) << ","
        << csvNumber(run.slip_updates_gated_pct) << ","
        << (m && m->diagnostics ? std::to_string(findings) : std::string());
    for (const std::string& e : kEstimators) {
      const eval::EstimatorMetrics* em = nullptr;
      if (m) {
        for (const eval::EstimatorMetrics& x : m->estimators)
          if (x.estimator == e) em = &x;
      }
      for (const std::string& key : kMetrics) {
        const auto v = em ? em->metrics.get(key) : std::nullopt;
        csv << "," << (v ? csvNumber(*v) : std::string());
      }
    }
    csv << "\n";
  }
  io::writeFileAtomically(out_dir / "summary.csv", csv.str());
  return static_cast<int>(folders.size());
}

Command addSummarizeCommand(CLI::App& app, const GlobalOptions& global) {
  auto dir = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "summarize",
      "Rebuild OUTDIR/summary.csv from the finished log folders of `traverse run A B ... -o "
      "OUTDIR` (e.g. after a cluster ran one log per task into the same OUTDIR)");
  cmd->add_option("OUTDIR", *dir, "The output directory holding one folder per log")->required();
  return [cmd, dir, &global]() {
    if (!*cmd) return -1;
    if (!fs::is_directory(*dir)) throw InputError(*dir, 0, "not a directory");
    const int rows = writeSummary(*dir);
    if (!global.quiet)
      std::cout << "wrote " << (fs::path(*dir) / "summary.csv").string() << " (" << rows
                << " logs)\n";
    return 0;
  };
}

}  // namespace traverse::app
