#include <gtest/gtest.h>

#include <cstdlib>
#include <ctime>

int main(int argc, char** argv) {
  // Tests must not depend on C's global RNG; seed it anyway so any stray use is reproducible.
  std::srand(20170101);
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
