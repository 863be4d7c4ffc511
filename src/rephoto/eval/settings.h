// The settings of `rephoto evaluate` by name: one table shared by the command-line flags
// (--name) and the config file keys (name), so an experiment file holds exactly what the flags
// hold. Flags override the file (the CLI applies the file first, then the flags given).
//
// Config file: TOML (.toml) or JSON (.json), chosen by the extension; a flat table of
// name = value at the top level. Key spelling: the flag name without "--"; '_' and '-' are the
// same ("image_root" = "image-root"). Values: strings, integers, floats, booleans; "metrics"
// also as an array of names. Relative paths (scene, image-root, model when no reconstruct
// command is set, photo-masks, out) are relative to the config file's folder; command templates
// are kept as written. An unknown key, a value of the wrong type, a nested table or an
// unparsable file is an Error naming the file and the key.
//
// Boolean flags come in pairs on the command line: --colorize / --no-colorize.
//
// Thread safety: pure functions of their arguments (the settings table is immutable).
#pragma once

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "rephoto/eval/options.h"

namespace rephoto::eval {

enum class SettingType { kString, kPath, kInt, kDouble, kBool, kMetricList };

struct SettingInfo {
  std::string name;  // flag name without "--", e.g. "train-short-side"
  SettingType type;
  std::string help;  // one line for --help
};

// Every setting, in --help order.
const std::vector<SettingInfo>& Settings();

// A value from the command line (always a string, or a bool for flags) or a config file.
using SettingValue = std::variant<std::string, int64_t, double, bool, std::vector<std::string>>;

// Sets `name` (either spelling) in `options`. `source` names where the value came from for
// messages ("--spp", "exp.toml: key 'spp'"); relative paths are resolved against `base_dir`
// unless it is empty. Throws UsageError "<source>: ..." for an unknown name or a bad value.
void ApplySetting(EvaluateOptions* options, std::string_view name, const SettingValue& value,
                  std::string_view source, const std::filesystem::path& base_dir = {});

// Reads a config file (see above) into `options`; records it in options->config_file.
// Tables (TOML) or objects (JSON) named in `extra_tables` are not settings: they are returned
// in `tables` (by name, as JSON; e.g. the [sweep] table of `rephoto sweep`) instead of being
// an error.
void LoadConfigFile(const std::filesystem::path& file, EvaluateOptions* options,
                    const std::vector<std::string>& extra_tables = {},
                    nlohmann::json* tables = nullptr);

// The same from the file's text (tests, fuzzers): `file` names it in messages, picks the format
// by its extension and is the base of relative paths; nothing is read from disk.
void LoadConfigText(std::string_view text, const std::filesystem::path& file,
                    EvaluateOptions* options, const std::vector<std::string>& extra_tables = {},
                    nlohmann::json* tables = nullptr);

// All settings with their resolved values, by name (for run.json).
nlohmann::ordered_json SettingsJson(const EvaluateOptions& options);

}  // namespace rephoto::eval
