// SPDX-License-Identifier: Apache-2.0
// The one outcome type: a code and a message.
#include <gtest/gtest.h>

#include <tinyline/common/status.hpp>

namespace c = tinyline::common;

TEST(Status, OkHasNoMessage) {
  const c::Status s;
  EXPECT_TRUE(s.ok());
  EXPECT_TRUE(s.message.empty());
  EXPECT_EQ(s.str(), "ok");
  EXPECT_TRUE(s.within("dbscan").ok());
}

TEST(Status, WithinPrefixesTheMessageAndKeepsTheCode) {
  const c::Status s = c::Status::invalid("eps must be > 0");
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.code, c::StatusCode::InvalidArgument);
  EXPECT_EQ(s.within("dbscan").message, "dbscan: eps must be > 0");
  EXPECT_EQ(s.within("clustering").within("surface").message, "surface: clustering: eps must be > 0");
  EXPECT_EQ(c::Status::not_found("no circle").within("fit").code, c::StatusCode::NotFound);
}

TEST(Status, StrNamesTheCode) {
  EXPECT_EQ(c::Status(c::StatusCode::CrcMismatch, "a.mcap: chunk at byte 12").str(),
            "crc mismatch: a.mcap: chunk at byte 12");
  EXPECT_EQ(c::Status::invalid("x").str(), "invalid argument: x");
}

TEST(Status, TheOlderValidationConvertsBothWays) {
  const c::Validation v = c::Status::invalid("eps must be > 0");
  EXPECT_FALSE(v.valid);
  EXPECT_EQ(v.reason, "eps must be > 0");
  const c::Status s = c::Validation::invalid("min_points must be >= 1");
  EXPECT_EQ(s.code, c::StatusCode::InvalidArgument);
  EXPECT_EQ(s.message, "min_points must be >= 1");
  EXPECT_TRUE(static_cast<c::Status>(c::Validation::ok()).ok());
  EXPECT_EQ(c::Validation::invalid("a").within("b").reason, "b: a");
}
