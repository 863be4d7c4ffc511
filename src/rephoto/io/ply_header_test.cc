#include "rephoto/io/ply_header.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sstream>
#include <string>

#include "rephoto/testing/testing.h"

namespace rephoto::io {
namespace {

using ::testing::HasSubstr;

TEST(PlyHeader, ParsesElementsPropertiesListsAndComments) {
  const std::string header =
      "ply\r\nformat binary_little_endian 1.0\r\ncomment TextureFile tex 1.png\r\n"
      "element vertex 18446744073709551615\r\nproperty float x\r\nproperty uchar red\r\n"
      "obj_info made by hand\r\n\r\nelement face 2\r\n"
      "property list uchar int vertex_indices\r\nend_header\r\n";
  const std::string body = "BODY";
  for (bool stream : {false, true}) {
    PlyHeader h;
    std::istringstream in(header + body);
    if (stream) {
      h = ReadPlyHeader(in, "a.ply");
    } else {
      h = ParsePlyHeader(header + body, "a.ply");
    }
    EXPECT_EQ(h.encoding, PlyEncoding::kBinaryLittleEndian);
    ASSERT_EQ(h.elements.size(), 2u);
    EXPECT_EQ(h.elements[0].name, "vertex");
    EXPECT_EQ(h.elements[0].count, 18446744073709551615ull);
    ASSERT_EQ(h.elements[0].properties.size(), 2u);
    EXPECT_EQ(h.elements[0].properties[1].name, "red");
    EXPECT_EQ(h.elements[0].properties[1].type, PlyType::kUInt8);
    EXPECT_EQ(h.elements[0].RecordBytes(), 5u);
    EXPECT_EQ(h.elements[0].Find("red"), 1);
    EXPECT_FALSE(h.elements[0].HasList());
    const PlyProperty& list = h.elements[1].properties[0];
    EXPECT_TRUE(list.is_list);
    EXPECT_EQ(list.count_type, PlyType::kUInt8);
    EXPECT_EQ(list.type, PlyType::kInt32);
    EXPECT_EQ(h.elements[1].Find("vertex_indices"), -1);  // lists are not scalars
    EXPECT_EQ(h.Find("face"), &h.elements[1]);
    EXPECT_EQ(h.Find("edge"), nullptr);
    EXPECT_EQ(h.comments, std::vector<std::string>{"TextureFile tex 1.png"});
    EXPECT_EQ(h.bytes, header.size());
    if (stream) {
      std::string rest;
      in >> rest;
      EXPECT_EQ(rest, body);
    }
  }
}

TEST(PlyHeader, RefusesMalformedHeadersWithOneLineNamingTheFileAndLine) {
  const std::string start = "ply\nformat ascii 1.0\nelement vertex 1\n";
  struct Case {
    std::string text, message;
  };
  for (const Case& c : {
           Case{"PLY\n", "m.ply: not a PLY file (no 'ply' magic)"},
           Case{"", "m.ply: not a PLY file"},
           Case{start + "property fancy x\nend_header\n", "m.ply: header line 4: bad property"},
           Case{start + "property float\nend_header\n", "header line 4: bad property"},
           Case{start + "property list float int i\nend_header\n",
                "header line 4: list count type must be an integer"},
           Case{start + "property list uchar int\nend_header\n", "header line 4: bad list"},
           Case{"ply\nformat ascii 1.0\nelement vertex -1\nend_header\n",
                "header line 3: bad element line"},
           Case{"ply\nformat ascii 1.0\nelement vertex 18446744073709551616\nend_header\n",
                "header line 3: bad element line"},
           Case{"ply\nformat ascii 1.0\nelement vertex 12x\nend_header\n", "bad element line"},
           Case{"ply\nformat ebcdic 1.0\nend_header\n", "header line 2: unknown format 'ebcdic'"},
           Case{"ply\nproperty float x\n", "header line 2: property before any element"},
           Case{start + "vertex_count 3\nend_header\n", "header line 4: unknown keyword"},
           Case{"ply\nelement vertex 1\nend_header\n", "m.ply: header has no format line"},
           Case{start + "property float x\n", "m.ply: unexpected end of file in the header"},
           Case{"ply\n" + std::string(70000, 'c'), "m.ply: header line longer than 64 KiB"},
           Case{"ply\n" + std::string(20000, '\n') +
                    [] {
                      std::string lines;
                      for (int i = 0; i < 20000; ++i)
                        lines += "comment " + std::string(50, 'x') + "\n";
                      return lines;
                    }(),
                "m.ply: PLY header longer than 1 MiB"},
       }) {
    SCOPED_TRACE(c.message);
    EXPECT_THAT(testing::ErrorOf([&] { ParsePlyHeader(c.text, "m.ply"); }), HasSubstr(c.message));
    std::istringstream in(c.text);
    EXPECT_THAT(testing::ErrorOf([&] { ReadPlyHeader(in, "m.ply"); }), HasSubstr(c.message));
  }
}

}  // namespace
}  // namespace rephoto::io
