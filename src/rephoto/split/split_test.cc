#include "rephoto/split/split.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/split/random.h"
#include "rephoto/testing/testing.h"

namespace rephoto::split {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

std::vector<std::string> Names(int count) {
  std::vector<std::string> names;
  for (int i = count - 1; i >= 0; --i) names.push_back(fmt::format("img{:02d}.png", i));
  return names;  // reverse order on purpose: splits sort by name
}

Scheme KFold(int k, uint64_t seed) {
  Scheme scheme;
  scheme.kind = SchemeKind::kKFold;
  scheme.folds = k;
  scheme.seed = seed;
  return scheme;
}

using testing::ErrorOf;

// Published SplitMix64 outputs (Vigna's splitmix64.c; also computed by
// testdata/make_split_fixture.py).
TEST(RandomTest, SplitMix64ReferenceValues) {
  SplitMix64 zero(0);
  EXPECT_EQ(zero.Next(), 0xe220a8397b1dcdafULL);
  EXPECT_EQ(zero.Next(), 0x6e789e6aa1b965f4ULL);
  EXPECT_EQ(zero.Next(), 0x06c45d188009454fULL);
  SplitMix64 other(1234567);
  EXPECT_EQ(other.Next(), 6457827717110365317ULL);
  EXPECT_EQ(other.Next(), 3203168211198807973ULL);
  EXPECT_EQ(other.Next(), 9817491932198370423ULL);
}

TEST(RandomTest, ShuffleMatchesIndependentReference) {
  // testdata/expected.txt: shuffle(range(10), 42).
  std::vector<int> items = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
  SeededShuffle(items, 42);
  EXPECT_THAT(items, ElementsAre(0, 9, 5, 8, 6, 4, 7, 2, 1, 3));
}

TEST(RandomTest, UniformBelowIsUniform) {
  SplitMix64 rng(5);
  std::vector<int> counts(7, 0);
  for (int i = 0; i < 70000; ++i) ++counts[rng.UniformBelow(7)];
  for (int count : counts) EXPECT_NEAR(count, 10000, 400);  // ~4 sigma
}

TEST(SplitTest, ParseSchemes) {
  EXPECT_EQ(ParseScheme("kfold:5").ToString(), "kfold:5:0");
  EXPECT_EQ(ParseScheme("kfold:5:99").seed, 99u);
  EXPECT_EQ(ParseScheme("loo").kind, SchemeKind::kLeaveOneOut);
  EXPECT_EQ(ParseScheme("every:8").every, 8);
  EXPECT_EQ(ParseScheme("fraction:0.25:3").ToString(), "fraction:0.25:3");
  EXPECT_EQ(ParseScheme("lists:a.txt,b.txt").test_list, "b.txt");
  EXPECT_EQ(ParseScheme("none").kind, SchemeKind::kNone);
  EXPECT_THAT(ErrorOf([] { ParseScheme("kfold:1"); }), HasSubstr("K = 1 must be at least 2"));
  EXPECT_THAT(ErrorOf([] { ParseScheme("kfold:x"); }), HasSubstr("K must be an integer"));
  EXPECT_THAT(ErrorOf([] { ParseScheme("fraction:1.5"); }), HasSubstr("strictly between 0 and 1"));
  EXPECT_THAT(ErrorOf([] { ParseScheme("every"); }), HasSubstr("expected every:N"));
  EXPECT_THAT(ErrorOf([] { ParseScheme("lists:a.txt"); }), HasSubstr("lists:TRAIN_FILE,TEST_FILE"));
  EXPECT_THAT(ErrorOf([] { ParseScheme("random"); }),
              HasSubstr("unknown scheme 'random' (supported: kfold:K[:SEED], loo"));
}

TEST(SplitTest, KFoldMatchesReferenceAndIsAPartition) {
  const Split split = MakeSplit(Names(10), ParseScheme("kfold:3:42"));
  ASSERT_EQ(split.folds.size(), 3u);
  // testdata/expected.txt (independent Python implementation).
  EXPECT_THAT(split.folds[0].test, ElementsAre("img00.png", "img03.png", "img07.png", "img08.png"));
  EXPECT_THAT(split.folds[1].test, ElementsAre("img02.png", "img06.png", "img09.png"));
  EXPECT_THAT(split.folds[2].test, ElementsAre("img01.png", "img04.png", "img05.png"));
  EXPECT_TRUE(split.cross_validated);
}

TEST(SplitTest, KFoldPropertiesForManySizesAndSeeds) {
  for (int n : {2, 3, 7, 10, 33}) {
    for (int k : {2, 3, 5}) {
      if (k > n) continue;
      for (uint64_t seed : {0ULL, 1ULL, 12345ULL}) {
        const std::vector<std::string> names = Names(n);
        const Split split = MakeSplit(names, KFold(k, seed));
        ASSERT_EQ(split.folds.size(), static_cast<size_t>(k));
        std::multiset<std::string> tested;
        size_t min_size = n, max_size = 0;
        for (const Fold& fold : split.folds) {
          tested.insert(fold.test.begin(), fold.test.end());
          min_size = std::min(min_size, fold.test.size());
          max_size = std::max(max_size, fold.test.size());
          EXPECT_EQ(fold.train.size() + fold.test.size(), static_cast<size_t>(n));
          for (const std::string& name : fold.test) {
            EXPECT_FALSE(std::binary_search(fold.train.begin(), fold.train.end(), name));
          }
          EXPECT_TRUE(std::is_sorted(fold.train.begin(), fold.train.end()));
        }
        EXPECT_EQ(tested, std::multiset<std::string>(names.begin(), names.end()));  // once each
        EXPECT_LE(max_size - min_size, 1u);
      }
    }
  }
  // Same seed, same split; another seed, (here) another split.
  const Scheme a = KFold(4, 7);
  const Scheme b = KFold(4, 8);
  EXPECT_EQ(MakeSplit(Names(20), a).folds[0].test, MakeSplit(Names(20), a).folds[0].test);
  EXPECT_NE(MakeSplit(Names(20), a).folds[0].test, MakeSplit(Names(20), b).folds[0].test);
}

TEST(SplitTest, LeaveOneOut) {
  const Split split = MakeSplit(Names(4), ParseScheme("loo"));
  ASSERT_EQ(split.folds.size(), 4u);
  EXPECT_THAT(split.folds[2].test, ElementsAre("img02.png"));
  EXPECT_THAT(split.folds[2].train, ElementsAre("img00.png", "img01.png", "img03.png"));
}

TEST(SplitTest, InterleavedKeepsNeighboursInDifferentFolds) {
  // 8 photos along a path, 3 folds: photo i (by name) is tested in fold i mod 3.
  const Split split = MakeSplit(Names(8), ParseScheme("interleaved:3"));
  ASSERT_EQ(split.folds.size(), 3u);
  EXPECT_THAT(split.folds[0].test, ElementsAre("img00.png", "img03.png", "img06.png"));
  EXPECT_THAT(split.folds[1].test, ElementsAre("img01.png", "img04.png", "img07.png"));
  EXPECT_THAT(split.folds[2].test, ElementsAre("img02.png", "img05.png"));
  EXPECT_THAT(split.folds[2].train, ElementsAre("img00.png", "img01.png", "img03.png", "img04.png",
                                                "img06.png", "img07.png"));
  EXPECT_TRUE(split.cross_validated);
  EXPECT_EQ(split.scheme.ToString(), "interleaved:3");
  EXPECT_THROW(ParseScheme("interleaved:3:1"), UsageError);
  EXPECT_THROW(ParseScheme("interleaved:1"), UsageError);
  EXPECT_THROW(MakeSplit(Names(2), ParseScheme("interleaved:3")), Error);
}

TEST(SplitTest, EveryNthStartsAtIndexZero) {
  // NeRF/3DGS "llffhold": sorted by name, test iff index % 8 == 0.
  const Split split = MakeSplit(Names(20), ParseScheme("every:8"));
  ASSERT_EQ(split.folds.size(), 1u);
  EXPECT_THAT(split.folds[0].test, ElementsAre("img00.png", "img08.png", "img16.png"));
  EXPECT_EQ(split.folds[0].train.size(), 17u);
}

TEST(SplitTest, FractionMatchesReference) {
  const Split split = MakeSplit(Names(10), ParseScheme("fraction:0.3:7"));
  EXPECT_THAT(split.folds[0].test, ElementsAre("img01.png", "img05.png", "img08.png"));
  EXPECT_EQ(split.folds[0].train.size(), 7u);
  // At least one test and one training image.
  EXPECT_EQ(MakeSplit(Names(3), ParseScheme("fraction:0.01")).folds[0].test.size(), 1u);
  EXPECT_EQ(MakeSplit(Names(3), ParseScheme("fraction:0.99")).folds[0].train.size(), 1u);
}

TEST(SplitTest, ListsAndNone) {
  const auto dir = testing::MakeTempDir();
  WriteTextFileAtomically(dir / "train.txt", "# training\nimg00.png\n./img01.png\n\n");
  WriteTextFileAtomically(dir / "test.txt", "img03.png\n");
  Scheme scheme = ParseScheme(
      fmt::format("lists:{},{}", (dir / "train.txt").string(), (dir / "test.txt").string()));
  const Split split = MakeSplit(Names(4), scheme);
  EXPECT_THAT(split.folds[0].train, ElementsAre("img00.png", "img01.png"));
  EXPECT_THAT(split.folds[0].test, ElementsAre("img03.png"));
  WriteTextFileAtomically(dir / "test.txt", "img03.png\nimg07.png\n");
  EXPECT_THAT(ErrorOf([&] { MakeSplit(Names(4), scheme); }),
              HasSubstr("test.txt:2: image 'img07.png' is not in the scene"));
  WriteTextFileAtomically(dir / "test.txt", "img01.png\n");
  EXPECT_THAT(ErrorOf([&] { MakeSplit(Names(4), scheme); }),
              HasSubstr("test.txt:1: image 'img01.png' is already listed at"));

  const Split none = MakeSplit(Names(3), ParseScheme("none"));
  EXPECT_FALSE(none.cross_validated);
  EXPECT_EQ(none.folds[0].train, none.folds[0].test);
}

TEST(SplitTest, SchemeDoesNotFit) {
  EXPECT_THAT(ErrorOf([] { MakeSplit(Names(3), ParseScheme("kfold:4")); }),
              HasSubstr("needs 2 <= K <= number of images (3)"));
  // A scheme that does not fit the data is a usage error (the CLI exits 2), as a malformed one.
  EXPECT_THROW(MakeSplit(Names(3), ParseScheme("kfold:4")), UsageError);
  EXPECT_THROW(MakeSplit(Names(1), ParseScheme("every:2")), UsageError);
  EXPECT_THROW(MakeSplit(Names(1), ParseScheme("fraction:0.5")), UsageError);
  EXPECT_THAT(ErrorOf([] {
                MakeSplit({"a", "a"}, ParseScheme("loo"));
              }),
              HasSubstr("'a' occurs twice"));
}

}  // namespace
}  // namespace rephoto::split
