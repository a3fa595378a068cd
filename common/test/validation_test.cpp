// SPDX-License-Identifier: Apache-2.0
// The one way to say "these parameters are invalid".
#include <gtest/gtest.h>

#include <tinyline/common/validation.hpp>

namespace c = tinyline::common;

TEST(Validation, OkIsValidWithoutReason) {
  const c::Validation v = c::Validation::ok();
  EXPECT_TRUE(v.valid);
  EXPECT_TRUE(v.reason.empty());
  EXPECT_TRUE(v.within("dbscan").valid);
}

TEST(Validation, WithinPrefixesTheReasonOfAnInvalidOne) {
  const c::Validation v = c::Validation::invalid("eps must be > 0");
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.within("dbscan").reason, "dbscan: eps must be > 0");
  EXPECT_EQ(v.within("clustering").within("surface").reason, "surface: clustering: eps must be > 0");
}
