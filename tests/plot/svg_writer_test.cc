// Well-formed XML: the tests' own checker, and EscapeXml.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "strokelab/plot/svg_plot.h"
#include "svg_test_util.h"

namespace strokelab::plot {
namespace {

using namespace svg_test;

TEST(XmlCheckerTest, CatchesWhatItShould) {
  EXPECT_EQ(XmlProblem("<a x=\"1\"><b/>t &amp; u</a>"), "");
  EXPECT_NE(XmlProblem("<a><b></a></b>"), "");
  EXPECT_NE(XmlProblem("<a>x < y</a>"), "");
  EXPECT_NE(XmlProblem("<a>x & y</a>"), "");
  EXPECT_NE(XmlProblem("<a x=1/>"), "");
  EXPECT_NE(XmlProblem("<a>"), "");
  EXPECT_NE(XmlProblem("<a/><b/>"), "");
}

TEST(EscapeXmlTest, EscapesMarkupAndDropsControlCharacters) {
  EXPECT_EQ(EscapeXml("<a href=\"x\">&</a>"), "&lt;a href=&quot;x&quot;&gt;&amp;&lt;/a&gt;");
  EXPECT_EQ(EscapeXml("tab\there\x07"), "tab\there");
  EXPECT_EQ(EscapeXml("\u00b5m"), "\u00b5m");  // UTF-8 passes through
}

}  // namespace
}  // namespace strokelab::plot
