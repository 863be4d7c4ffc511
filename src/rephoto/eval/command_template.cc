#include "rephoto/eval/command_template.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <set>
#include <thread>

#include "rephoto/core/file.h"
#include "rephoto/core/process.h"

extern char** environ;

namespace rephoto::eval {
namespace fs = std::filesystem;

namespace {

bool IsPlaceholderChar(char c) {
  return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
}

// Walks the template: calls literal(text) and placeholder(name) in order.
template <typename Literal, typename Placeholder>
void ParseTemplate(std::string_view text, Literal&& literal, Placeholder&& placeholder) {
  size_t i = 0;
  while (i < text.size()) {
    const char c = text[i];
    if (c == '{' && i + 1 < text.size() && text[i + 1] == '{') {
      literal("{");
      i += 2;
      continue;
    }
    if (c == '}' && i + 1 < text.size() && text[i + 1] == '}') {
      literal("}");
      i += 2;
      continue;
    }
    if (c == '{' && (i == 0 || text[i - 1] != '$')) {
      size_t j = i + 1;
      while (j < text.size() && IsPlaceholderChar(text[j])) ++j;
      if (j > i + 1 && j < text.size() && text[j] == '}') {
        placeholder(std::string(text.substr(i + 1, j - i - 1)));
        i = j + 1;
        continue;
      }
    }
    literal(text.substr(i, 1));
    ++i;
  }
}

std::string KnownList(const std::vector<std::string>& known) {
  std::string list;
  for (const std::string& name : known) {
    if (!list.empty()) list += ", ";
    list += "{" + name + "}";
  }
  return list;
}

}  // namespace

std::vector<std::string> TemplatePlaceholders(std::string_view command_template,
                                              const std::vector<std::string>& known,
                                              std::string_view what) {
  std::set<std::string> names;
  const std::set<std::string> known_set(known.begin(), known.end());
  ParseTemplate(
      command_template, [](std::string_view) {},
      [&](const std::string& name) {
        if (!known_set.count(name)) {
          throw UsageError(
              fmt::format("{}: unknown placeholder {{{}}} (known: {}; write {{{{ and "
                          "}}}} for literal braces)",
                          what, name, KnownList(known)));
        }
        names.insert(name);
      });
  return {names.begin(), names.end()};
}

std::string SubstitutePlaceholders(std::string_view command_template,
                                   const std::map<std::string, std::string>& values,
                                   std::string_view what) {
  std::string out;
  ParseTemplate(
      command_template, [&](std::string_view text) { out += text; },
      [&](const std::string& name) {
        const auto it = values.find(name);
        if (it == values.end()) {
          std::vector<std::string> known;
          for (const auto& [key, value] : values) known.push_back(key);
          throw UsageError(fmt::format("{}: unknown placeholder {{{}}} (known: {})", what, name,
                                       KnownList(known)));
        }
        out += ShellQuote(it->second);
      });
  return out;
}

// ------------------------------------------------------------------------------ interrupts

namespace {

std::atomic<bool> g_interrupted{false};
std::atomic<int> g_guards{0};
struct sigaction g_previous_int, g_previous_term;

// Process groups of running commands, so the signal handler can stop them.
constexpr int kMaxChildren = 64;
std::array<std::atomic<pid_t>, kMaxChildren> g_children{};

void OnSignal(int signal) {
  if (g_interrupted.exchange(true)) {
    // Second signal: give up at once, as the user asked twice.
    ::signal(signal, SIG_DFL);
    ::raise(signal);
    return;
  }
  for (auto& child : g_children) {
    const pid_t pid = child.load();
    if (pid > 0) ::kill(-pid, SIGTERM);
  }
  static const char kMessage[] =
      "\nrephoto: interrupted: finishing the view in flight; rerun the same command to resume "
      "(press Ctrl-C again to stop at once)\n";
  [[maybe_unused]] const ssize_t n = ::write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
}

int RegisterChild(pid_t pid) {
  for (int i = 0; i < kMaxChildren; ++i) {
    pid_t expected = 0;
    if (g_children[i].compare_exchange_strong(expected, pid)) return i;
  }
  return -1;
}

}  // namespace

InterruptGuard::InterruptGuard() {
  if (g_guards.fetch_add(1) == 0) {
    struct sigaction action {};
    action.sa_handler = OnSignal;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESTART;
    ::sigaction(SIGINT, &action, &g_previous_int);
    ::sigaction(SIGTERM, &action, &g_previous_term);
  }
}

InterruptGuard::~InterruptGuard() {
  if (g_guards.fetch_sub(1) == 1) {
    ::sigaction(SIGINT, &g_previous_int, nullptr);
    ::sigaction(SIGTERM, &g_previous_term, nullptr);
  }
}

bool InterruptRequested() { return g_interrupted.load(); }
void RequestInterrupt(bool value) { g_interrupted.store(value); }

// ------------------------------------------------------------------------------- running

ShellOutcome RunShellCommand(const std::string& command, const fs::path& log_file,
                               std::string_view header, double timeout_seconds) {
  std::error_code ec;
  if (!log_file.parent_path().empty()) fs::create_directories(log_file.parent_path(), ec);
  {
    std::ofstream log(log_file, std::ios::binary | std::ios::trunc);
    REPHOTO_CHECK(log.good(), "{}: cannot create the log file", log_file.string());
    log << "# " << header << "\n# $ " << command << "\n";
    REPHOTO_CHECK(log.good(), "{}: cannot write the log file", log_file.string());
  }

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  const std::string log_path = log_file.string();
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_path.c_str(),
                                   O_WRONLY | O_APPEND | O_CREAT, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  const ChildSpawnAttributes attributes;  // own group, default signals (core/process.h)

  const char* argv[] = {"/bin/sh", "-c", command.c_str(), nullptr};
  const auto start = std::chrono::steady_clock::now();
  pid_t pid = 0;
  const int spawned =
      posix_spawn(&pid, "/bin/sh", &actions, attributes.get(), const_cast<char* const*>(argv),
                  environ);
  posix_spawn_file_actions_destroy(&actions);
  REPHOTO_CHECK(spawned == 0, "{}: cannot start /bin/sh: {}", log_file.string(),
                std::strerror(spawned));
  const int slot = RegisterChild(pid);

  ShellOutcome outcome;
  int status = 0;
  struct rusage usage {};
  bool terminated = false;
  auto kill_time = std::chrono::steady_clock::time_point::max();
  const auto deadline =
      timeout_seconds > 0 ? start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                        std::chrono::duration<double>(timeout_seconds))
                          : std::chrono::steady_clock::time_point::max();
  for (;;) {
    const pid_t done = ::wait4(pid, &status, WNOHANG, &usage);
    if (done == pid) break;
    if (done == -1 && errno != EINTR) break;
    if (!outcome.timed_out && std::chrono::steady_clock::now() >= deadline) {
      outcome.timed_out = true;
      std::ofstream(log_file, std::ios::binary | std::ios::app) << fmt::format(
          "\n# rephoto: timed out after {:g} s (--command-timeout); stopping the "
          "command's process group\n",
          timeout_seconds);
    }
    if (InterruptRequested() || outcome.timed_out) {
      outcome.interrupted = InterruptRequested();
      const auto now = std::chrono::steady_clock::now();
      if (!terminated) {
        ::kill(-pid, SIGTERM);
        terminated = true;
        kill_time = now + std::chrono::seconds(5);
      } else if (now > kill_time) {
        ::kill(-pid, SIGKILL);
        kill_time = std::chrono::steady_clock::time_point::max();
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // Whatever the command left in its group (a pipeline's stage that ignored SIGTERM) ends
  // with it when it was stopped.
  if (terminated) ::kill(-pid, SIGKILL);
  if (slot >= 0) g_children[slot].store(0);
  outcome.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  outcome.cpu_seconds = CpuSeconds(usage);
  if (WIFEXITED(status)) outcome.exit_status = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) outcome.signal = WTERMSIG(status);
  if (InterruptRequested()) outcome.interrupted = true;
  return outcome;
}

std::string LastLogLine(const fs::path& log_file, size_t max_chars) {
  std::ifstream in(log_file, std::ios::binary);
  std::string line, last;
  for (int index = 0; std::getline(in, line); ++index) {
    if (index < 2) continue;  // the header RunShellCommand wrote
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (!line.empty()) last = line;
  }
  if (last.size() > max_chars) last = last.substr(0, max_chars) + "...";
  return last;
}

}  // namespace rephoto::eval
