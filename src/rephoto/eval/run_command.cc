#include "rephoto/eval/run_command.h"

#include "rephoto/core/process.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/eval/run_records.h"
#include "rephoto/io/image_io.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

namespace {

// The command failed (the first message is kept).
void FailCommand(CommandOutcome& command, const std::string& message) {
  command.ok = false;
  if (command.message.empty()) command.message = message;
}

std::string CommandKey(const RunContext& s, const FoldPlan& fold) {
  Hasher key;
  key.Add(kKeyVersion)
      .Add(s.CommandKind())
      .Add(s.CommandTemplate())
      .AddInt(static_cast<int64_t>(fold.index));
  key.Add(fold.train_key).Add(fold.test_key);
  if (s.source == ModelSource::kReconstruct) key.Add(s.options.model.generic_string());
  if (s.source == ModelSource::kRender) key.AddInt(s.options.eval_short_side);
  return key.Hex();
}

std::string SubstitutedCommand(const RunContext& s, const FoldPlan& fold) {
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
  return SubstitutePlaceholders(s.CommandTemplate(), values, std::string("--") + s.CommandKind());
}

// An external renderer's output: one image per test view at the evaluation size.
bool ValidateRenderings(const RunContext& s, const FoldPlan& fold, const std::string& head,
                        const std::string& log, CommandOutcome& command) {
  std::vector<std::string> missing, wrong, unreadable;
  for (const TestView& test : fold.tests) {
    const fs::path image = FindImageByStem(fold.out_dir, test.stem);
    if (image.empty()) {
      missing.push_back(test.stem);
      continue;
    }
    try {
      const io::ImageHeader header = io::ReadImageHeader(image);
      if (!s.options.resize &&
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
    FailCommand(command,
                fmt::format("{} wrote {} of {} images (missing: {}); see {}", head,
                            fold.tests.size() - missing.size(), fold.tests.size(), list, log));
    return false;
  }
  if (!unreadable.empty()) {
    FailCommand(command, fmt::format("{} wrote {} unreadable image(s) ({}{}); see {}", head,
                                     unreadable.size(), unreadable[0],
                                     unreadable.size() > 1 ? ", ..." : "", log));
    return false;
  }
  if (!wrong.empty()) {
    FailCommand(command, fmt::format("{} wrote {} image(s) of the wrong size ({}{}); see {}", head,
                                     wrong.size(), wrong[0], wrong.size() > 1 ? ", ..." : "", log));
    return false;
  }
  return true;
}

bool ValidateCommandOutput(const RunContext& s, const FoldPlan& fold, CommandOutcome& command) {
  const std::string log = s.Relative(fold.log_file);
  const std::string head =
      fmt::format("{}: {} command '{}'", fold.name, s.CommandKind(), Shorten(s.CommandTemplate()));
  std::error_code ec;
  bool empty = true;
  for (fs::directory_iterator it(fold.out_dir, ec), end; !ec && it != end; it.increment(ec)) {
    empty = false;
    break;
  }
  if (empty) {
    FailCommand(command, fmt::format("{} wrote nothing into {}; see {}", head,
                                     s.Relative(fold.out_dir), log));
    return false;
  }
  if (s.source == ModelSource::kReconstruct) {
    const fs::path model = fold.out_dir / s.options.model;
    if (!fs::is_regular_file(model, ec)) {
      FailCommand(command,
                  fmt::format("{} wrote no model {}; see {}", head, s.Relative(model), log));
      return false;
    }
    command.model_path = model;
    return true;
  }
  return ValidateRenderings(s, fold, head, log, command);
}

// Reuses the recorded command result when its key matches and the outputs are still valid.
// Reuses the recorded command result when its key matches and the outputs are still valid.
// When they are not, `command` keeps the recorded times and status (as fold.json then says).
bool ReuseCommand(const RunContext& s, const FoldPlan& fold, CommandOutcome& command) {
  if (!fold.previous || !fold.previous->contains("command")) return false;
  const Json& previous = (*fold.previous)["command"];
  if (previous.value("key", "") != command.key || previous.value("status", "") != "ok") {
    return false;
  }
  command.reused = true;
  command.seconds = previous.value("seconds", 0.0);
  command.cpu_seconds = previous.value("cpu_seconds", 0.0);
  command.status = "ok";
  if (ValidateCommandOutput(s, fold, command)) return true;
  // The outputs changed since: run the command again.
  command.reused = false;
  command.ok = true;
  command.message.clear();
  return false;
}

std::string FailureReason(const RunContext& s, const ShellOutcome& outcome) {
  if (outcome.timed_out) {
    return fmt::format("timed out after {:g} s, --command-timeout", s.options.command_timeout);
  }
  if (outcome.signal != 0) return fmt::format("killed by signal {}", outcome.signal);
  return fmt::format("exit status {}{}", outcome.exit_status,
                     outcome.exit_status == 127 ? ", command not found" : "");
}

}  // namespace

CommandOutcome RunFoldCommand(const RunContext& s, const FoldPlan& fold, bool may_run,
                              Tally& tally) {
  CommandOutcome command;
  command.key = CommandKey(s, fold);
  command.command = SubstitutedCommand(s, fold);
  if (ReuseCommand(s, fold, command)) return command;
  if (!may_run) {
    FailCommand(command,
                fmt::format("{}: not reconstructed yet: its {} command has no finished result "
                            "with these settings (run the fold's task first)",
                            fold.name, s.CommandKind()));
    return command;
  }
  std::error_code ec;
  fs::remove_all(fold.out_dir, ec);
  fs::create_directories(fold.out_dir, ec);
  REPHOTO_CHECK(!ec, "{}: cannot create: {}", fold.out_dir.string(), ec.message());
  // Forget the previous command result before starting a new one.
  command.status = "running";
  FoldOutcome running;
  running.command = command;
  WriteFoldJson(s, fold, running, "running");
  LogInfo(fmt::format("{}: running the {} command (log: {})", fold.name, s.CommandKind(),
                      fold.log_file.string()));
  const ShellOutcome outcome = RunShellCommand(
      command.command, fold.log_file,
      fmt::format("rephoto evaluate {} {}", fold.name, s.CommandKind()), s.options.command_timeout);
  tally.Count(&EvaluateCounters::commands_run);
  tally.AddSeconds(&EvaluateTimings::external, outcome.seconds);
  tally.AddSeconds(&EvaluateTimings::external_cpu, outcome.cpu_seconds);
  command.external_seconds = outcome.seconds;
  command.seconds = outcome.seconds;
  command.cpu_seconds = outcome.cpu_seconds;
  command.exit_status = outcome.exit_status;
  command.status = "failed";
  if (outcome.interrupted) {
    command.interrupted = true;
    command.ok = false;
    return command;
  }
  if (!outcome.ok()) {
    const std::string last = LastLogLine(fold.log_file);
    FailCommand(command, fmt::format("{}: {} command '{}' failed ({}); see {}{}", fold.name,
                                     s.CommandKind(), Shorten(s.CommandTemplate()),
                                     FailureReason(s, outcome), s.Relative(fold.log_file),
                                     last.empty() ? "" : " (last line: " + last + ")"));
    return command;
  }
  const bool valid = ValidateCommandOutput(s, fold, command);
  if (valid) command.status = "ok";
  LogInfo(fmt::format("{}: {} command finished in {:.1f} s{}", fold.name, s.CommandKind(),
                      outcome.seconds, valid ? "" : " (failed)"));
  return command;
}

}  // namespace rephoto::eval
