// SPDX-License-Identifier: Apache-2.0
// Text from files shown to a person: what would not be seen is escaped.
#include <gtest/gtest.h>

#include <tinyline/common/visible_text.hpp>

using tinyline::common::visible;

TEST(VisibleText, PlainTextAndUtf8PassUnchanged) {
  EXPECT_EQ(visible("/demo/raw"), "/demo/raw");
  EXPECT_EQ(visible("Gr\xc3\xbc\xc3\x9f"
                    "e \xe2\x82\xac"),
            "Gr\xc3\xbc\xc3\x9f"
            "e \xe2\x82\xac");
  EXPECT_EQ(visible(""), "");
}

// Regression: `bag info` showed a byte-order mark invisibly and a lone byte as '?'.
TEST(VisibleText, InvisibleCodePointsControlsAndLoneBytesAreEscaped) {
  EXPECT_EQ(visible("\xef\xbb\xbfros2"), "\\ufeffros2");
  EXPECT_EQ(visible("a\xff"), "a\\xff");
  EXPECT_EQ(visible("\xc3"), "\\xc3");                    // a sequence cut short
  EXPECT_EQ(visible("\xc0\xaf"), "\\xc0\\xaf");           // an overlong '/'
  EXPECT_EQ(visible("\xed\xa0\x80"), "\\xed\\xa0\\x80");  // a surrogate
  EXPECT_EQ(visible("a\x01"
                    "b\x7f"),
            "a\\x01b\\x7f");
  EXPECT_EQ(visible("line\nnext\t\r"), "line\\nnext\\t\\r");
  EXPECT_EQ(visible("\xe2\x80\x8b\xe2\x80\xae\xc2\x85"), "\\u200b\\u202e\\u0085");
  EXPECT_EQ(visible("a\\xff"), "a\\\\xff");  // a backslash is escaped too: no two texts look alike
}
