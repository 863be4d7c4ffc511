// Fuzzes the checks of request fields of `rephoto serve` (src/rephoto/service/text.h): the
// input is a request target "PATH?QUERY" (or anything), decoded as the server decodes it
// (cpp-httplib's decode_url and parse_query_text), then checked as the server checks it, plus
// a method name and a description (the input itself). Invariants: the checks throw Refused or
// nothing; Printable's output is always clean text; clean text always serialises as strict
// JSON (so a stored value can never make a response fail); a one-line clean text is multi-line
// clean too.
#include <httplib.h>

#include <nlohmann/json.hpp>

#include "fuzz_common.h"
#include "rephoto/service/archive.h"
#include "rephoto/service/text.h"

using rephoto::service::CheckRequestTarget;
using rephoto::service::CheckRequestText;
using rephoto::service::IsCleanText;
using rephoto::service::Printable;
using rephoto::service::Refused;
using rephoto::service::TextPolicy;

namespace {

void Check(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "invariant broken: %s\n", what);
    std::abort();
  }
}

void CheckText(const std::string& text) {
  const bool one_line = IsCleanText(text);
  const bool multi_line = IsCleanText(text, TextPolicy::kMultiLine);
  Check(!one_line || multi_line, "one-line clean text is not multi-line clean");
  if (multi_line) {
    try {
      (void)nlohmann::json(text).dump();  // strict: throws on invalid UTF-8
    } catch (const std::exception&) {
      Check(false, "clean text does not serialise as JSON");
    }
  }
  Check(IsCleanText(Printable(text)), "Printable gave text that is not clean");
  Check(IsCleanText(Printable(text, 7)), "Printable (cut) gave text that is not clean");
  try {
    CheckRequestText(text, "the method name", 1, 100);
    Check(one_line && !text.empty() && text.size() <= 100, "a bad method name passed");
  } catch (const Refused& refused) {
    Check(refused.status == 400, "a method name refused with a status other than 400");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string input(rephoto::fuzz::AsText(data, size));
  CheckText(input);
  const size_t question = input.find('?');
  const std::string path = httplib::detail::decode_url(input.substr(0, question), false);
  httplib::Params params;
  if (question != std::string::npos) {
    httplib::detail::parse_query_text(input.substr(question + 1), params);
  }
  bool clean = IsCleanText(path);
  for (const auto& [key, value] : params) {
    clean = clean && IsCleanText(key) && IsCleanText(value, TextPolicy::kMultiLine);
    CheckText(key);
    CheckText(value);
  }
  try {
    CheckRequestTarget(path, params);
    Check(clean, "a request target with unclean text passed");
  } catch (const Refused& refused) {
    Check(refused.status == 400 && !clean, "a clean request target refused");
    CheckText(refused.what());
  }
  return 0;
}
