#include "rephoto/sweep/table.h"

#include <gtest/gtest.h>

#include <fstream>

#include "rephoto/core/error.h"
#include "rephoto/io/csv.h"
#include "rephoto/testing/testing.h"

namespace rephoto::sweep {
namespace {

TEST(SweepTable, StatisticsAcrossFoldsFromEachRunsPerFoldCsv) {
  const auto dir = testing::MakeTempDir();
  const std::vector<SweepAxis> axes = {{"train_count", {4, 2, 1}}};
  const auto settings = ExpandGrid(axes);
  // Setting 0: four folds; setting 1: two folds, one failed; setting 2: not run yet.
  testing::WriteFile(dir / "a" / "per_fold.csv",
                     "fold,status,test_images,evaluated_images,seconds,completeness,1-ncc,cb+cr\n"
                     "fold_00,ok,2,2,1.5,0.9,0.1,0.02\n"
                     "fold_01,ok,2,2,1.5,0.8,0.4,0.03\n"
                     "fold_02,ok,2,2,1.5,1.0,0.2,0.01\n"
                     "fold_03,ok,2,2,1.5,0.7,0.3,\n");
  // As evaluate writes it: the message column last (text, not a measurement).
  testing::WriteFile(
      dir / "b" / "per_fold.csv",
      "fold,status,test_images,evaluated_images,seconds,completeness,1-ncc,cb+cr,message\n"
      "fold_00,ok,2,2,1.5,0.5,0.6,0.05,\n"
      "fold_01,failed,2,0,0.1,,,,fold_01: reconstruct command failed (exit status 1)\n");
  const SweepTable table = ReadSweepTable(settings, {dir / "a", dir / "b", dir / "c"});
  ASSERT_EQ(table.columns, (std::vector<std::string>{"completeness", "1-ncc", "cb+cr"}));
  ASSERT_EQ(table.settings.size(), 3u);
  // Hand computation, numpy type-7 quantiles of {0.1, 0.2, 0.3, 0.4}: q1 at position 0.75 ->
  // 0.175, median 0.25, q3 at 2.25 -> 0.325.
  const Summary& ncc = table.settings[0].across_folds[1];
  EXPECT_EQ(ncc.count, 4u);
  EXPECT_NEAR(ncc.median, 0.25, 1e-12);
  EXPECT_NEAR(ncc.q1, 0.175, 1e-12);
  EXPECT_NEAR(ncc.q3, 0.325, 1e-12);
  EXPECT_NEAR(ncc.mean, 0.25, 1e-12);
  EXPECT_EQ(table.settings[0].across_folds[2].count, 3u);  // one fold without cb+cr
  EXPECT_EQ(table.settings[1].failed_folds, 1u);
  EXPECT_EQ(table.settings[1].across_folds[0].count, 1u);  // the failed fold is left out
  EXPECT_EQ(table.settings[2].folds.size(), 0u);

  const auto summary = io::ParseCsv(SweepSummaryCsv(table, axes), "sweep.csv");
  ASSERT_EQ(summary.size(), 4u);
  EXPECT_EQ(summary[0][0], "setting");
  EXPECT_EQ(summary[0][1], "train_count");
  EXPECT_EQ(summary[0][2], "folds");
  EXPECT_EQ(summary[0][10], "1-ncc_median");
  EXPECT_EQ(summary[1][0], "train_count-4");
  EXPECT_EQ(summary[1][1], "4");
  EXPECT_EQ(summary[1][2], "4");
  EXPECT_EQ(summary[1][10], "0.25");
  EXPECT_EQ(summary[2][3], "1");  // failed folds
  EXPECT_EQ(summary[3][2], "0");
  EXPECT_EQ(summary[3][10], "");

  const auto per_fold = io::ParseCsv(SweepPerFoldCsv(table, axes), "sweep_per_fold.csv");
  ASSERT_EQ(per_fold.size(), 1u + 4u + 2u);
  EXPECT_EQ(per_fold[0], (std::vector<std::string>{"setting", "train_count", "fold", "status",
                                                   "completeness", "1-ncc", "cb+cr"}));
  EXPECT_EQ(per_fold[6],
            (std::vector<std::string>{"train_count-2", "2", "fold_01", "failed", "", "", ""}));
}

TEST(SweepTable, MalformedPerFoldCsvNamesTheFile) {
  const auto dir = testing::MakeTempDir();
  testing::WriteFile(dir / "a" / "per_fold.csv", "fold,status,completeness\nfold_00,ok,abc\n");
  try {
    ReadSweepTable(ExpandGrid({}), {dir / "a"});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "per_fold.csv: line 2: column \"completeness\": \"abc\" is not a number"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace rephoto::sweep
