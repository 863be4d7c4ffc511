// The encodings every file of a run folder shares (docs/run-folder.md): numbers that may be NaN
// or infinite in JSON and CSV, the five-number summaries of summary.json, and JSON records
// (summary.json, run.json, fold.json, views/<stem>.json) read back for resuming.
//
// Numbers. JSON has no NaN or infinity: NaN ("nothing evaluated") is written as null, +inf and
// -inf as the strings "inf" and "-inf". CSV fields: NaN is the empty field, infinities "inf" and
// "-inf" (io::CsvNumber writes them); readers also accept "+inf".
//
// Thread safety: free functions without shared state; safe to call from any thread.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>

#include "rephoto/core/stats.h"

namespace rephoto::run {

using Json = nlohmann::ordered_json;

// A double as JSON: null for NaN, "inf"/"-inf" for infinities, else the number.
Json JsonNumber(double value);

// The inverse of JsonNumber: numbers as they are, "inf"/"-inf"/"+inf" as infinities, anything
// else (null, other strings, objects) as NaN.
double NumberFromJson(const Json& value);

// A CSV field as a number: "" = NaN, "inf"/"+inf"/"-inf", else a decimal number
// (std::from_chars: the whole field, no spaces, no leading '+'). Returns std::nullopt when the
// field is not a number.
std::optional<double> ParseCsvNumber(std::string_view field);

// A five-number summary with its mean and count, as in summary.json:
//   {"mean", "min", "q1", "median", "q3", "max", <count_key>}
// `count_key` is the schema's name of the count: "images" in `rephoto compare`'s summary.json
// (rephoto.compare/1), "count" in `rephoto evaluate`'s (rephoto.evaluate/1), where a summary may
// count folds.
Json SummaryJson(const Summary& summary, std::string_view count_key);

// A JSON file written by a run, or std::nullopt when it does not exist or cannot be parsed (a
// damaged record is recomputed, not an error).
std::optional<Json> ReadJsonRecord(const std::filesystem::path& path);

// Writes `json` indented by 2 with a final newline, atomically (core/file.h).
void WriteJsonRecord(const std::filesystem::path& path, const Json& json);

}  // namespace rephoto::run
