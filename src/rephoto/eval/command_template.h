// External commands of `rephoto evaluate`: placeholder templates and running them through
// /bin/sh with their output captured to a log file.
//
// Template syntax: "{name}" where name is one or more of [a-z0-9_] is a placeholder, replaced
// by its value shell-quoted (single quotes; an embedded ' becomes '\''), so paths with spaces
// or quotes reach the command as one word. "{{" and "}}" stand for literal braces. A '{' right
// after '$' is never a placeholder, so shell variables like ${HOME} pass through unchanged.
// Any other brace text (e.g. awk's '{print $1}', which has a space) is kept as it is.
// An unknown placeholder is an error listing the known ones.
//
// Thread safety: SubstitutePlaceholders and TemplatePlaceholders are pure; RunShellCommand may
// run from several threads at once (evaluate runs `jobs` commands in worker threads); the
// interrupt flag is one process-wide atomic, and one InterruptGuard should live at a time.
#pragma once

#include <atomic>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/process.h"

namespace rephoto::eval {

// A bad setting (core/error.h; the CLI exits with ExitCode::kUsage).
using ::rephoto::UsageError;

// `value` as one POSIX shell word (core/process.h).
using ::rephoto::ShellQuote;

// The placeholder names used in `command_template` (sorted, unique). Throws UsageError
// "<what>: unknown placeholder {x} (known: {a}, {b}, ...)" when one is not in `known`.
std::vector<std::string> TemplatePlaceholders(std::string_view command_template,
                                              const std::vector<std::string>& known,
                                              std::string_view what);

// Substitutes the placeholders (values shell-quoted). Throws UsageError as above for a name
// without a value.
std::string SubstitutePlaceholders(std::string_view command_template,
                                   const std::map<std::string, std::string>& values,
                                   std::string_view what);

struct ShellOutcome {
  int exit_status = 0;       // the shell's exit status (127: command not found)
  int signal = 0;            // terminating signal, 0 if it exited
  bool interrupted = false;  // stopped because the run was interrupted (SIGINT/SIGTERM)
  bool timed_out = false;    // stopped because it ran longer than the timeout
  double seconds = 0;        // wall-clock time
  // CPU time (user + system) of the shell and every descendant it waited for (wait4's rusage):
  // what the command cost, independent of what else the machine ran meanwhile.
  double cpu_seconds = 0;
  bool ok() const { return exit_status == 0 && signal == 0 && !interrupted && !timed_out; }
};

// Runs `/bin/sh -c command` in its own process group, stdin from /dev/null, stdout and stderr
// appended to `log_file` (created with a header line naming the command; an existing log is
// replaced). Waits for it. When InterruptRequested() becomes true while it runs, the whole
// process group gets SIGTERM (SIGKILL 5 s later) and the outcome is `interrupted`. Likewise when
// it runs longer than `timeout_seconds` (> 0; 0 = no limit): the outcome is `timed_out` and the
// log ends with a line saying so. A stopped command's group gets SIGKILL once the shell is
// gone, so no stage of a pipeline outlives it. Throws Error naming the log file when it cannot
// be created or the shell cannot be started.
ShellOutcome RunShellCommand(const std::string& command, const std::filesystem::path& log_file,
                               std::string_view header, double timeout_seconds = 0);

// The last non-empty line of a log file (at most `max_chars`), "" if none; for messages.
std::string LastLogLine(const std::filesystem::path& log_file, size_t max_chars = 200);

// Interrupt handling. While an InterruptGuard lives, SIGINT and SIGTERM set the interrupt flag
// (and stop running commands) instead of killing the process; the previous handlers are
// restored by its destructor. A second signal while interrupted terminates at once.
class InterruptGuard {
 public:
  InterruptGuard();
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;
};
bool InterruptRequested();
// Sets or clears the flag (tests; also what the signal handler does).
void RequestInterrupt(bool value = true);

}  // namespace rephoto::eval
