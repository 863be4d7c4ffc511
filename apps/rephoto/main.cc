// rephoto: novel view prediction error for 3D reconstruction (virtual rephotography).
// Exit codes: see rephoto::ExitCode in src/rephoto/core/error.h.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
#include "rephoto/core/limits.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/process.h"
#include "rephoto/core/progress.h"

namespace rephoto::cli {

// CLI11's help prints a switch with a "--no-" form as "--x,--no-x{false}"; the braces are
// CLI11's syntax, not the default (which the help text states), so they are left out.
class HelpFormatter : public CLI::Formatter {
 public:
  std::string make_option_name(const CLI::Option* option, bool positional) const override {
    std::string name = CLI::Formatter::make_option_name(option, positional);
    for (const char* braces : {"{false}", "{true}"}) {
      for (size_t at; (at = name.find(braces)) != std::string::npos;) {
        name.erase(at, std::string_view(braces).size());
      }
    }
    return name;
  }
};

std::vector<CommandInfo>& CommandTable() {
  static std::vector<CommandInfo> table;
  return table;
}
}  // namespace rephoto::cli

int main(int argc, char** argv) {
  using namespace rephoto;
  KeepFreedMemory();  // large buffers are reused instead of page-faulted again (core/process.h)
  CLI::App app{
      "rephoto: how good does a 3D reconstruction look? Virtual rephotography "
      "(Waechter et al. 2017): render held-out views and compare them with the photos."};
  // The version and the instruction-set path the kernels take (core/isa.h: REPHOTO_ISA).
  app.set_version_flag(
      "--version", fmt::format("{}\nisa: {}", REPHOTO_VERSION, core::IsaName(core::ActiveIsa())));
  app.formatter(std::make_shared<cli::HelpFormatter>());
  app.require_subcommand(1);
  // A mistake in the options: one line naming it, then where the options are listed (the same
  // form as the usage errors the commands find in their settings).
  app.failure_message([](const CLI::App* top, const CLI::Error& e) {
    const auto subcommands = top->get_subcommands();
    const std::string help = subcommands.empty()
                                 ? "rephoto --help"
                                 : "rephoto " + subcommands[0]->get_name() + " --help";
    return fmt::format("rephoto: {}\nRun '{}' for the options.\n", e.what(), help);
  });
  int threads = 0;
  bool quiet = false;
  app.add_option("-j,--threads", threads,
                 "Worker threads (0 = all cores, or $SLURM_CPUS_PER_TASK inside a Slurm job)")
      ->capture_default_str();
  app.add_flag("-q,--quiet", quiet, "Only print warnings and errors");
  // Resource limits for the files read (core/limits.h): a file whose header claims more is an
  // error naming it, before anything is allocated.
  uint64_t max_pixels = MaxPixels();
  std::string max_memory;
  app.add_option("--max-pixels", max_pixels,
                 "Largest image read, in pixels (default 2^28 = 16384x16384)")
      ->capture_default_str()
      ->check([](const std::string& text) {
        return text.find_first_not_of('0') == std::string::npos ? "must be at least 1" : "";
      });
  app.add_option("--max-memory", max_memory,
                 fmt::format("Most memory one input (model, image) may need once read, e.g. 16G, "
                             "512M or bytes (default: half the physical memory, here {})",
                             FormatBytes(DefaultMaxMemoryBytes())))
      ->check([](const std::string& text) {
        try {
          ParseByteSize(text);
          return std::string();
        } catch (const Error& e) {
          const std::string message = e.what();  // "--max-memory: ...": CLI11 names the option
          return message.substr(message.find(": ") + 2);
        }
      });

  auto& table = cli::CommandTable();
  std::sort(table.begin(), table.end(),
            [](const auto& a, const auto& b) { return a.order < b.order; });
  std::vector<std::pair<CLI::App*, cli::CommandRunner>> commands;
  for (const auto& command : table) {
    CLI::App* sub = app.add_subcommand(command.name, command.description);
    commands.emplace_back(sub, command.setup(*sub));
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : static_cast<int>(ExitCode::kUsage);
  }

  SetQuiet(quiet);
  SetMaxPixels(max_pixels);
  if (!max_memory.empty()) SetMaxMemoryBytes(ParseByteSize(max_memory));
  // Inside a Slurm job without -j: the CPUs the job was given, not every core of a shared node.
  if (threads == 0) {
    if (const char* slurm_cpus = std::getenv("SLURM_CPUS_PER_TASK"))
      threads = std::atoi(slurm_cpus);
  }
  ThreadLimit thread_limit(std::max(threads, 0));
  try {
    core::CheckIsaEnvironment();
    for (auto& [sub, run] : commands) {
      if (sub->parsed()) return run();
    }
  } catch (const UsageError& e) {
    std::fflush(stdout);
    fmt::print(stderr, "rephoto: error: {}\n", e.what());
    return static_cast<int>(ExitCode::kUsage);
  } catch (const Interrupted& e) {
    std::fflush(stdout);
    fmt::print(stderr, "rephoto: {}\n", e.what());
    return static_cast<int>(ExitCode::kInterrupted);
  } catch (const Error& e) {
    std::fflush(stdout);
    fmt::print(stderr, "rephoto: error: {}\n", e.what());
    return static_cast<int>(ExitCode::kFailure);
  } catch (const std::bad_alloc&) {
    fmt::print(stderr, "rephoto: error: out of memory\n");
    return static_cast<int>(ExitCode::kFailure);
  } catch (const std::exception& e) {
    fmt::print(stderr, "rephoto: internal error: {}\n", e.what());
    return static_cast<int>(ExitCode::kFailure);
  }
  return static_cast<int>(ExitCode::kUsage);
}
