#include "rephoto/run/records.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::run {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(RunRecords, JsonNumbersRoundTripNanAndInfinities) {
  EXPECT_EQ(JsonNumber(kNaN).dump(), "null");
  EXPECT_EQ(JsonNumber(kInf).dump(), "\"inf\"");
  EXPECT_EQ(JsonNumber(-kInf).dump(), "\"-inf\"");
  EXPECT_EQ(JsonNumber(0.25).dump(), "0.25");
  for (double v : {0.25, -3.0, kInf, -kInf}) EXPECT_EQ(NumberFromJson(JsonNumber(v)), v);
  EXPECT_TRUE(std::isnan(NumberFromJson(JsonNumber(kNaN))));
  EXPECT_TRUE(std::isnan(NumberFromJson(Json("fast"))));
  EXPECT_EQ(NumberFromJson(Json("+inf")), kInf);
}

TEST(RunRecords, CsvNumbersAcceptOnlyWholeFields) {
  EXPECT_TRUE(std::isnan(*ParseCsvNumber("")));
  EXPECT_EQ(*ParseCsvNumber("inf"), kInf);
  EXPECT_EQ(*ParseCsvNumber("+inf"), kInf);
  EXPECT_EQ(*ParseCsvNumber("-inf"), -kInf);
  EXPECT_EQ(*ParseCsvNumber("0.125"), 0.125);
  EXPECT_EQ(*ParseCsvNumber("-2e-3"), -2e-3);
  EXPECT_FALSE(ParseCsvNumber("0.1x"));
  EXPECT_FALSE(ParseCsvNumber(" 1"));
  EXPECT_FALSE(ParseCsvNumber("abc"));
}

TEST(RunRecords, SummaryJsonNamesTheCountAsTheSchemaDoes) {
  Summary s;
  s.mean = 0.5;
  s.min = 0;
  s.q1 = 0.25;
  s.median = 0.5;
  s.q3 = 0.75;
  s.max = 1;
  s.count = 5;
  EXPECT_EQ(SummaryJson(s, "images").dump(),
            R"({"mean":0.5,"min":0.0,"q1":0.25,"median":0.5,"q3":0.75,"max":1.0,"images":5})");
  EXPECT_EQ(SummaryJson(s, "count").dump(),
            R"({"mean":0.5,"min":0.0,"q1":0.25,"median":0.5,"q3":0.75,"max":1.0,"count":5})");
}

TEST(RunRecords, DamagedOrMissingRecordsReadAsAbsent) {
  const auto dir = testing::MakeTempDir();
  EXPECT_FALSE(ReadJsonRecord(dir / "none.json"));
  WriteTextFileAtomically(dir / "bad.json", "{\"key\": ");
  EXPECT_FALSE(ReadJsonRecord(dir / "bad.json"));
  WriteJsonRecord(dir / "ok.json", Json{{"key", "abc"}, {"value", JsonNumber(kInf)}});
  EXPECT_EQ(ReadFileToString(dir / "ok.json"), "{\n  \"key\": \"abc\",\n  \"value\": \"inf\"\n}\n");
  const auto back = ReadJsonRecord(dir / "ok.json");
  ASSERT_TRUE(back);
  EXPECT_EQ(NumberFromJson((*back)["value"]), kInf);
}

}  // namespace
}  // namespace rephoto::run

#include "rephoto/run/summary_table.h"

namespace rephoto::run {
namespace {

TEST(SummaryTable, ColumnsAndSpecialValues) {
  Summary s;
  s.mean = 0.25;
  s.min = 0;
  s.median = std::numeric_limits<double>::quiet_NaN();
  s.max = std::numeric_limits<double>::infinity();
  const std::string text = FormatSummaryTable(
      "over images", "mean", {{"completeness", s, 0, false}, {"1-ncc", s, 0.5, true}});
  EXPECT_EQ(text,
            "over images          mean        min     median        max     pooled\n"
            "completeness       0.2500     0.0000          -        inf           \n"
            "1-ncc              0.2500     0.0000          -        inf     0.5000\n");
}

}  // namespace
}  // namespace rephoto::run
