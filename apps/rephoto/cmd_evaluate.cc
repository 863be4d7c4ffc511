// rephoto evaluate --scene SCENE [--format F] [--image-root DIR] [--scheme S]
//                  (--model FILE | --reconstruct 'CMD' --model PATH_IN_OUT | --render 'CMD')
//                  [--colorize] [--train-count N] [--train-short-side PX] [--eval-short-side PX]
//                  [--metrics ...] [--window N] [--spp N] [--jobs N] ... --out RUN
// rephoto evaluate --config experiment.toml [flags overriding the file]
// Every setting is both a flag (--name) and a config key (name); the table is in
// src/rephoto/eval/settings.cc, the behaviour in src/rephoto/eval/evaluate.h.
#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <string>

#include "command.h"
#include "rephoto/cluster/slurm_settings.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/eval/evaluate.h"
#include "rephoto/eval/result_text.h"
#include "rephoto/eval/settings.h"
#include "rephoto/eval/slurm_executor.h"
#include "slurm_args.h"

namespace rephoto::cli {
namespace {

struct EvaluateArguments {
  std::string config;
  std::map<std::string, std::string> strings;  // by setting name
  std::map<std::string, bool> flags;
  std::map<std::string, CLI::Option*> options;
  std::string only;
  int views_per_task = 16;
  ExecutorArguments executor;
};

// The process's arguments (Linux /proc/self/cmdline), recorded in run.json.
std::vector<std::string> CommandLine() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::vector<std::string> args;
  std::string arg;
  while (std::getline(in, arg, '\0')) args.push_back(arg);
  return args;
}

// The [slurm] table of a config file (cluster/slurm_settings.h keys) as SlurmOptions.
cluster::SlurmOptions SlurmTable(const nlohmann::json& tables, const std::string& config) {
  cluster::SlurmOptions base;
  if (tables.is_object() && tables.contains("slurm")) {
    cluster::ApplySlurmTable(base, tables["slurm"], config);
  }
  return base;
}

CommandRunner SetupEvaluate(CLI::App& app) {
  auto args = std::make_shared<EvaluateArguments>();
  app.add_option("--config", args->config,
                 "Experiment file (.toml or .json) with the same settings as the flags; flags "
                 "override it")
      ->check(CLI::ExistingFile);
  app.add_option("--only", args->only,
                 "Run one task of a prepared run instead of the whole run: fold:F, "
                 "views:F:FIRST:COUNT or aggregate (what --executor slurm submits; see "
                 "docs/cluster.md)");
  app.add_option("--views-per-task", args->views_per_task,
                 "Held-out views per Slurm task (--executor slurm)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  AddExecutorOptions(app, &args->executor);
  const nlohmann::ordered_json defaults = eval::SettingsJson(eval::EvaluateOptions{});
  for (const eval::SettingInfo& info : eval::Settings()) {
    const std::string flag = "--" + info.name;
    const nlohmann::ordered_json& value = defaults.at(info.name);
    std::string default_text;
    if (info.name == "metrics") {
      default_text = "all";
    } else if (info.name == "compat-metrics") {
      default_text = "the preset's: psnr,ssim";
    } else if (value.is_string()) {
      default_text = value.get<std::string>();
    } else {
      default_text = value.dump();
    }
    const std::string help =
        default_text.empty() ? info.help : info.help + " [default: " + default_text + "]";
    if (info.type == eval::SettingType::kBool) {
      args->flags[info.name] = false;
      args->options[info.name] =
          app.add_flag(flag + ",!--no-" + info.name, args->flags[info.name], help)
              ->disable_flag_override();
    } else {
      static const std::map<eval::SettingType, std::string> kTypeNames = {
          {eval::SettingType::kString, "TEXT"},
          {eval::SettingType::kPath, "PATH"},
          {eval::SettingType::kInt, "INT"},
          {eval::SettingType::kDouble, "FLOAT"},
          {eval::SettingType::kMetricList, "LIST"}};
      args->strings[info.name];
      args->options[info.name] =
          app.add_option(flag, args->strings[info.name], help)->type_name(kTypeNames.at(info.type));
    }
  }
  return [args]() {
    eval::EvaluateOptions options;
    options.handle_interrupts = true;
    try {
      nlohmann::json tables;
      if (!args->config.empty()) eval::LoadConfigFile(args->config, &options, {"slurm"}, &tables);
      for (const eval::SettingInfo& info : eval::Settings()) {
        const CLI::Option* option = args->options.at(info.name);
        if (option->count() == 0) continue;
        const std::string source = "--" + info.name;
        if (info.type == eval::SettingType::kBool) {
          eval::ApplySetting(&options, info.name, args->flags.at(info.name), source);
        } else {
          eval::ApplySetting(&options, info.name, args->strings.at(info.name), source);
        }
      }
      options.only = args->only;
      options.views_per_task = args->views_per_task;
      const std::optional<cluster::SlurmOptions> slurm =
          MakeSlurmOptions(args->executor, SlurmTable(tables, args->config));
      if (slurm) {
        options.executor = eval::Executor::kSlurm;
        options.slurm = *slurm;
      }
      options.Check();
    } catch (const eval::UsageError& e) {
      fmt::print(stderr, "rephoto: {}\nRun 'rephoto evaluate --help' for the options.\n", e.what());
      return static_cast<int>(ExitCode::kUsage);
    }
    options.command_line = CommandLine();
    if (options.executor == eval::Executor::kSlurm) {
      const eval::SlurmRunOutcome outcome = eval::RunEvaluateOnSlurm(options, eval::PlanEvaluate);
      PrintSlurmOutcome(outcome.run, "rephoto evaluate ... (the same command)");
      if (!outcome.finished) {
        return static_cast<int>(outcome.run.finished ? ExitCode::kIncomplete : ExitCode::kOk);
      }
      fmt::print("{}", eval::ResultText(outcome.result, options.out));
      return static_cast<int>(outcome.result.exit_code);
    }
    const eval::EvaluateResult result = eval::RunEvaluate(options);
    if (!options.only.empty()) return static_cast<int>(result.exit_code);  // a task: no table

    fmt::print("{}", eval::ResultText(result, options.out));
    return static_cast<int>(result.exit_code);
  };
}

REPHOTO_COMMAND(45, "evaluate",
                "Virtual rephotography end to end: split, reconstruct or take a model per fold, "
                "rephotograph the held-out views, compare, aggregate, project, report",
                SetupEvaluate);

}  // namespace
}  // namespace rephoto::cli
