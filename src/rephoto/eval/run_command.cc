#include "rephoto/eval/run_command.h"

#include "rephoto/core/process.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/command.h"
#include "rephoto/eval/records.h"
#include "rephoto/io/image_io.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

namespace {

std::string CommandKey(const RunState& s, const FoldState& fold) {
  Hasher key;
  key.Add(kKeyVersion)
      .Add(s.CommandKind())
      .Add(s.CommandTemplate())
      .AddInt(static_cast<int64_t>(fold.index));
  key.Add(fold.train_key).Add(fold.test_key);
  if (s.source == ModelSource::kReconstruct) key.Add(s.o.model.generic_string());
  if (s.source == ModelSource::kRender) key.AddInt(s.o.eval_short_side);
  return key.Hex();
}

std::string SubstitutedCommand(const RunState& s, const FoldState& fold) {
  const std::map<std::string, std::string> values = {
      {"train", fold.train_dir.string()},
      {"sparse", (fold.train_dir / "sparse").string()},
      {"transforms", (fold.train_dir / "transforms.json").string()},
      {"images", fs::absolute(fold.images_dir).lexically_normal().string()},
      {"train_list", fold.train_list.string()},
      {"test", fold.test_dir.string()},
      {"test_sparse", (fold.test_dir / "sparse").string()},
      {"test_transforms", (fold.test_dir / "transforms.json").string()},
      {"test_list", fold.test_list.string()},
      {"out", fold.out_dir.string()},
      {"fold", std::to_string(fold.index)},
      {"threads", std::to_string(s.CommandThreads())}};
  return SubstitutePlaceholders(s.CommandTemplate(), values,
                                std::string("--") + s.CommandKind());
}

// An external renderer's output: one image per test view at the evaluation size.
bool ValidateRenderings(const RunState& s, FoldState& fold, const std::string& head,
                        const std::string& log) {
  std::vector<std::string> missing, wrong, unreadable;
  for (const TestView& test : fold.tests) {
    const fs::path image = FindImageByStem(fold.out_dir, test.stem);
    if (image.empty()) {
      missing.push_back(test.stem);
      continue;
    }
    try {
      const io::ImageHeader header = io::ReadImageHeader(image);
      if (!s.o.resize &&
          (header.width != test.camera.width || header.height != test.camera.height)) {
        wrong.push_back(fmt::format("{} is {}x{}, expected {}x{}", image.filename().string(),
                                    header.width, header.height, test.camera.width,
                                    test.camera.height));
      }
    } catch (const Error& e) {
      unreadable.push_back(e.what());
    }
  }
  if (!missing.empty()) {
    std::string list;
    for (size_t i = 0; i < missing.size() && i < 5; ++i) list += (i ? ", " : "") + missing[i];
    if (missing.size() > 5) list += ", ...";
    FailFold(fold, fmt::format("{} wrote {} of {} images (missing: {}); see {}", head,
                               fold.tests.size() - missing.size(), fold.tests.size(), list, log));
    return false;
  }
  if (!unreadable.empty()) {
    FailFold(fold,
             fmt::format("{} wrote {} unreadable image(s) ({}{}); see {}", head, unreadable.size(),
                         unreadable[0], unreadable.size() > 1 ? ", ..." : "", log));
    return false;
  }
  if (!wrong.empty()) {
    FailFold(fold, fmt::format("{} wrote {} image(s) of the wrong size ({}{}); see {}", head,
                               wrong.size(), wrong[0], wrong.size() > 1 ? ", ..." : "", log));
    return false;
  }
  return true;
}

bool ValidateCommandOutput(const RunState& s, FoldState& fold) {
  const std::string log = s.Relative(fold.log_file);
  const std::string head = fmt::format("{}: {} command '{}'", fold.name, s.CommandKind(),
                                       Shorten(s.CommandTemplate()));
  std::error_code ec;
  bool empty = true;
  for (fs::directory_iterator it(fold.out_dir, ec), end; !ec && it != end; it.increment(ec)) {
    empty = false;
    break;
  }
  if (empty) {
    FailFold(fold, fmt::format("{} wrote nothing into {}; see {}", head,
                               s.Relative(fold.out_dir), log));
    return false;
  }
  if (s.source == ModelSource::kReconstruct) {
    const fs::path model = fold.out_dir / s.o.model;
    if (!fs::is_regular_file(model, ec)) {
      FailFold(fold, fmt::format("{} wrote no model {}; see {}", head, s.Relative(model), log));
      return false;
    }
    fold.model_path = model;
    return true;
  }
  return ValidateRenderings(s, fold, head, log);
}

// Reuses the recorded command result when its key matches and the outputs are still valid.
bool ReuseCommand(const RunState& s, FoldState& fold) {
  if (!fold.previous || !fold.previous->contains("command")) return false;
  const Json& previous = (*fold.previous)["command"];
  if (previous.value("key", "") != fold.command_key || previous.value("status", "") != "ok") {
    return false;
  }
  fold.command_reused = true;
  fold.command_seconds = previous.value("seconds", 0.0);
  fold.command_cpu_seconds = previous.value("cpu_seconds", 0.0);
  fold.command_status = "ok";
  if (ValidateCommandOutput(s, fold)) return true;
  // The outputs changed since: run the command again.
  fold.command_reused = false;
  fold.ok = true;
  fold.message.clear();
  return false;
}

std::string FailureReason(const RunState& s, const CommandOutcome& outcome) {
  if (outcome.timed_out) {
    return fmt::format("timed out after {:g} s, --command-timeout", s.o.command_timeout);
  }
  if (outcome.signal != 0) return fmt::format("killed by signal {}", outcome.signal);
  return fmt::format("exit status {}{}", outcome.exit_status,
                     outcome.exit_status == 127 ? ", command not found" : "");
}

}  // namespace

void RunFoldCommand(RunState& s, FoldState& fold, bool may_run) {
  fold.command_key = CommandKey(s, fold);
  fold.command = SubstitutedCommand(s, fold);
  if (ReuseCommand(s, fold)) return;
  if (!may_run) {
    FailFold(fold, fmt::format("{}: not reconstructed yet: its {} command has no finished result "
                               "with these settings (run the fold's task first)",
                               fold.name, s.CommandKind()));
    return;
  }
  std::error_code ec;
  fs::remove_all(fold.out_dir, ec);
  fs::create_directories(fold.out_dir, ec);
  REPHOTO_CHECK(!ec, "{}: cannot create: {}", fold.out_dir.string(), ec.message());
  // Forget the previous command result before starting a new one.
  fold.command_status = "running";
  WriteFoldJson(s, fold, "running");
  LogInfo(fmt::format("{}: running the {} command (log: {})", fold.name, s.CommandKind(),
                      fold.log_file.string()));
  const CommandOutcome outcome = RunShellCommand(
      fold.command, fold.log_file,
      fmt::format("rephoto evaluate {} {}", fold.name, s.CommandKind()), s.o.command_timeout);
  {
    std::lock_guard<std::mutex> lock(s.timings_mutex);
    ++s.counters.commands_run;
    s.timings.external += outcome.seconds;
    s.timings.external_cpu += outcome.cpu_seconds;
  }
  fold.external_seconds = outcome.seconds;
  fold.command_seconds = outcome.seconds;
  fold.command_cpu_seconds = outcome.cpu_seconds;
  fold.exit_status = outcome.exit_status;
  fold.command_status = "failed";
  if (outcome.interrupted) {
    fold.interrupted = true;
    fold.command_ok = false;
    return;
  }
  if (!outcome.ok()) {
    const std::string last = LastLogLine(fold.log_file);
    FailFold(fold, fmt::format("{}: {} command '{}' failed ({}); see {}{}", fold.name,
                               s.CommandKind(), Shorten(s.CommandTemplate()),
                               FailureReason(s, outcome), s.Relative(fold.log_file),
                               last.empty() ? "" : " (last line: " + last + ")"));
    fold.command_ok = false;
    return;
  }
  fold.command_ok = ValidateCommandOutput(s, fold);
  if (fold.command_ok) fold.command_status = "ok";
  LogInfo(fmt::format("{}: {} command finished in {:.1f} s{}", fold.name, s.CommandKind(),
                      outcome.seconds, fold.command_ok ? "" : " (failed)"));
}


}  // namespace rephoto::eval
