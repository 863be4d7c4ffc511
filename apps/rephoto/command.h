// The rephoto CLI is a table of commands. Each command lives in its own cmd_<name>.cc, which
// registers itself with REPHOTO_COMMAND: a function that declares the command's options on a
// CLI11 subcommand and returns the function that runs it (parsed options captured by value
// or in a shared_ptr). Commands only parse options and call library code.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <vector>

namespace rephoto::cli {

using CommandRunner = std::function<int()>;  // returns a rephoto::ExitCode value
using CommandSetup = std::function<CommandRunner(CLI::App& subcommand)>;

struct CommandInfo {
  int order;  // position in `rephoto --help`
  std::string name;
  std::string description;
  CommandSetup setup;
};

std::vector<CommandInfo>& CommandTable();

struct CommandRegistrar {
  CommandRegistrar(int order, std::string name, std::string description, CommandSetup setup) {
    CommandTable().push_back({order, std::move(name), std::move(description), std::move(setup)});
  }
};

}  // namespace rephoto::cli

#define REPHOTO_COMMAND_CONCAT2(a, b) a##b
#define REPHOTO_COMMAND_CONCAT(a, b) REPHOTO_COMMAND_CONCAT2(a, b)
#define REPHOTO_COMMAND(order, name, description, setup)                                 \
  static ::rephoto::cli::CommandRegistrar REPHOTO_COMMAND_CONCAT(g_command_, __LINE__)( \
      order, name, description, setup)
