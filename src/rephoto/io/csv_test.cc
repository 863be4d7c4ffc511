#include "rephoto/io/csv.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::io {
namespace {

TEST(Csv, QuotesOnlyWhenNeeded) {
  EXPECT_EQ(CsvField("plain"), "plain");
  EXPECT_EQ(CsvField(""), "");
  EXPECT_EQ(CsvField("a,b"), "\"a,b\"");
  EXPECT_EQ(CsvField("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(CsvField("two\nlines"), "\"two\nlines\"");
  EXPECT_EQ(CsvField(" padded"), "\" padded\"");
}

TEST(Csv, NumbersRoundTripAndNanIsEmpty) {
  EXPECT_EQ(CsvNumber(0.1), "0.1");
  EXPECT_EQ(CsvNumber(2), "2");
  EXPECT_EQ(CsvNumber(std::nan("")), "");
  EXPECT_EQ(CsvNumber(-std::numeric_limits<double>::infinity()), "-inf");
  const double value = 1.0 / 3.0;
  EXPECT_EQ(std::stod(CsvNumber(value)), value);
}

TEST(Csv, WriterOutputParsesBack) {
  CsvWriter writer;
  writer.AddRow({"name", "value"});
  writer.AddRow({"a,b", "1"});
  writer.AddRow({"q\"uote", ""});
  writer.AddRow({"multi\nline", "x"});
  EXPECT_EQ(writer.text(), "name,value\n\"a,b\",1\n\"q\"\"uote\",\n\"multi\nline\",x\n");
  const auto rows = ParseCsv(writer.text(), "t.csv");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[1], (std::vector<std::string>{"a,b", "1"}));
  EXPECT_EQ(rows[2], (std::vector<std::string>{"q\"uote", ""}));
  EXPECT_EQ(rows[3], (std::vector<std::string>{"multi\nline", "x"}));
}

TEST(Csv, ParserAcceptsCrLfAndMissingFinalNewline) {
  const auto rows = ParseCsv("a,b\r\n1,2", "t.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(rows[1], (std::vector<std::string>{"1", "2"}));
}

TEST(Csv, UnterminatedQuoteNamesTheLine) {
  try {
    ParseCsv("a,b\n\"open,2\n", "t.csv");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "t.csv:2: unterminated quoted field");
  }
}

TEST(Csv, ReadCsvFileParsesTheFileAndNamesItWhenMissing) {
  const std::filesystem::path dir = testing::MakeTempDir();
  WriteTextFileAtomically(dir / "t.csv", "a,b\n\"x,y\",2\n");
  const auto rows = ReadCsvFile(dir / "t.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[1], (std::vector<std::string>{"x,y", "2"}));
  EXPECT_EQ(testing::ErrorOf([&] { ReadCsvFile(dir / "missing.csv"); }),
            (dir / "missing.csv").string() + ": cannot open: No such file or directory");
}

}  // namespace
}  // namespace rephoto::io
