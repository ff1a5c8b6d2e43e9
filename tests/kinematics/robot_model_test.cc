// kinematics/robot_model: hostile URDFs (issue 31). Elements nested 200,000 deep crashed TinyXML (it parses
// recursively): refused by a scan of the text before any parser sees it, with one line. A chain of 60,000 links
// took quadratic time (its loop check walked up from every joint, and lookups walked every joint): linear now.
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "kinematics/robot_model.h"

namespace driftlab::kinematics {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

TEST(HostileUrdf, ElementsNested200kDeepAreRefusedBeforeTheXmlIsParsed) {
  std::string xml = "<?xml version=\"1.0\"?>\n<!-- a <comment> -->\n<robot name=\"deep\">\n";
  for (int i = 0; i < 200'000; ++i) xml += "<a x=\"1>2\">";
  for (int i = 0; i < 200'000; ++i) xml += "</a>";
  xml += "\n</robot>\n";
  const auto t0 = std::chrono::steady_clock::now();
  auto m = RobotModel::parse(xml, "deep.urdf");
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().message,
            "deep.urdf:4: XML elements nested more than 1000 deep: refused before it is parsed (a URDF nests a few "
            "levels)");
  EXPECT_LT(seconds_since(t0), 5);
  // Self-closing elements, comments and quoted '>' do not nest.
  std::string flat = "<robot name=\"r\"><!-- <x> -->";
  for (int i = 0; i < 5000; ++i) flat += "<link name=\"l" + std::to_string(i) + "\"/>";
  EXPECT_TRUE(check_xml_depth(flat + "</robot>", "flat.urdf").ok());
}

TEST(HostileUrdf, AChainOf60kLinksIsReadInLinearTime) {
  constexpr int kLinks = 60'000;
  std::string xml = "<robot name=\"chain\">\n";
  for (int i = 0; i < kLinks; ++i) xml += "<link name=\"l" + std::to_string(i) + "\"/>\n";
  for (int i = 1; i < kLinks; ++i) {
    xml += "<joint name=\"j" + std::to_string(i) + "\" type=\"continuous\"><parent link=\"l" + std::to_string(i - 1) +
           "\"/><child link=\"l" + std::to_string(i) + "\"/><axis xyz=\"0 0 1\"/></joint>\n";
  }
  xml += "</robot>\n";
  const auto t0 = std::chrono::steady_clock::now();
  auto m = RobotModel::parse(xml, "chain.urdf");
  ASSERT_TRUE(m.ok()) << m.error().message;
  auto path = m->path("l0", "l" + std::to_string(kLinks - 1));
  ASSERT_TRUE(path.ok()) << path.error().message;
  EXPECT_EQ(path->size(), static_cast<size_t>(kLinks - 1));
  EXPECT_EQ(m->joint("j59999")->child, "l59999");
  EXPECT_LT(seconds_since(t0), 10);
  // A loop through the whole chain is still found, and named by the first joint in the file on it.
  const std::string loop = xml.substr(0, xml.size() - 9) +
                           "<joint name=\"back\" type=\"fixed\"><parent link=\"l59999\"/><child link=\"l0\"/>"
                           "</joint>\n</robot>\n";
  auto looped = RobotModel::parse(loop, "loop.urdf");
  ASSERT_FALSE(looped.ok());
  EXPECT_NE(looped.error().message.find("joint 'j1' closes a loop"), std::string::npos) << looped.error().message;
}

}  // namespace
}  // namespace driftlab::kinematics
