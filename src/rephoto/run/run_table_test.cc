#include "rephoto/run/run_table.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "rephoto/core/error.h"

namespace rephoto::run {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(RunTable, KindsFollowTheColumnNamesOnly) {
  for (const char* text : {"fold", "name", "status", "photo", "render", "message", "notes"}) {
    EXPECT_EQ(KindOfColumn(text), ColumnKind::kText) << text;
  }
  for (const char* integer : {"width", "height", "resized", "test_images", "evaluated_images",
                              "valid_photo_windows", "valid_both_windows", "1-ncc_evaluated",
                              "psnr_evaluated"}) {
    EXPECT_EQ(KindOfColumn(integer), ColumnKind::kInteger) << integer;
  }
  for (const char* number : {"completeness", "seconds", "1-ncc", "cb+cr", "dssim", "psnr"}) {
    EXPECT_EQ(KindOfColumn(number), ColumnKind::kNumber) << number;
  }
  // Not a metric: a column of a newer version, kept as text.
  EXPECT_EQ(KindOfColumn("lpips_evaluated_x"), ColumnKind::kText);
  EXPECT_EQ(KindOfColumn("_evaluated"), ColumnKind::kText);
  // evaluate --compat's columns: <preset>_<metric>.
  for (const char* number : {"3dgs_psnr", "3dgs_ssim", "nerfstudio_psnr"}) {
    EXPECT_EQ(KindOfColumn(number), ColumnKind::kNumber) << number;
  }
  EXPECT_EQ(KindOfColumn("3dgs_bogus"), ColumnKind::kText);
  EXPECT_EQ(KindOfColumn("mip_psnr"), ColumnKind::kText);
}

TEST(RunTable, EmptyNumbersAreNanEmptyCountsZeroAndShortRowsPadded) {
  const RunTable table = ParseRunTable(
      "fold,name,status,width,completeness,1-ncc,1-ncc_evaluated,notes\n"
      "fold_00,a,ok,640,0.5,0.25,1200,\"x, y\"\n"
      "fold_00,b,failed,,,,,\n"
      "fold_01,c,ok,8,inf,-inf,3\n",
      "per_image.csv");
  ASSERT_EQ(table.rows.size(), 3u);
  const int name = table.Column("name"), width = table.Column("width");
  const int ncc = table.Column("1-ncc"), evaluated = table.Column("1-ncc_evaluated");
  const int completeness = table.Column("completeness"), notes = table.Column("notes");
  EXPECT_EQ(table.Text(0, name), "a");
  EXPECT_EQ(table.Integer(0, width), 640);
  EXPECT_EQ(table.Number(0, completeness), 0.5);
  EXPECT_EQ(table.Number(0, ncc), 0.25);
  EXPECT_EQ(table.Integer(0, evaluated), 1200);
  EXPECT_EQ(table.Text(0, notes), "x, y");
  EXPECT_EQ(table.Integer(1, width), 0);
  EXPECT_TRUE(std::isnan(table.Number(1, completeness)));
  EXPECT_TRUE(std::isnan(table.Number(1, ncc)));
  EXPECT_EQ(table.Integer(1, evaluated), 0);
  EXPECT_EQ(table.Number(2, completeness), kInf);
  EXPECT_EQ(table.Number(2, ncc), -kInf);
  EXPECT_EQ(table.Text(2, notes), "");  // the short row's missing field
  EXPECT_EQ(table.Find("lpips"), -1);
}

TEST(RunTable, JunkIsAnErrorNamingFileLineAndColumn) {
  const auto expect_error = [](const char* text, const char* message) {
    try {
      ParseRunTable(text, "runs/a/per_image.csv");
      ADD_FAILURE() << "no error for " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  };
  expect_error("name,completeness\na,0.5\nb,half\n",
               "runs/a/per_image.csv: line 3: column \"completeness\": \"half\" is not a number");
  expect_error("name,width\na,12.5\n",
               "runs/a/per_image.csv: line 2: column \"width\": \"12.5\" is not an integer");
  expect_error("name,1-ncc\na,0.1,7\n", "runs/a/per_image.csv: line 2: 3 fields, the header has 2");
  expect_error("", "runs/a/per_image.csv: empty file");
  EXPECT_THROW(ParseRunTable("name\na\n", "t.csv").Column("status"), Error);
}

}  // namespace
}  // namespace rephoto::run
