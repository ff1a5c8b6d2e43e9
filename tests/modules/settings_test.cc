// Tests for modules/settings.h: a module config read and checked against the modules' tables without making any
// module, saying what making them (modules/registry.h, as `driftlab replay --config` does) would say.
#include "modules/settings.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "modules/registry.h"
#include "tests/test_util.h"

namespace driftlab::modules {
namespace {

/// The check's verdict on a config, and the registry's when it makes the same modules from the same file.
struct Verdicts {
  std::string check, make;
};

Verdicts judge(const test::TempDir& dir, const std::string& yaml, const std::string& modules) {
  const std::string path = dir.file("modules.yaml");
  std::ofstream(path) << yaml;
  Verdicts v;
  auto settings = read_module_settings(path);
  const Status checked = settings ? check_module_settings(*settings, modules) : Status{settings.error()};
  if (!checked) v.check = checked.message();
  std::vector<std::string> notes;
  auto made = load_modules(modules, path, {}, notes);
  if (!made) v.make = made.error().message;
  return v;
}

TEST(ModuleSettings, TheCheckSaysWhatMakingTheModulesWouldSay) {
  test::TempDir dir;
  const std::string all = "slam,estimator,controller,drone_estimator,flight,offboard";
  // Accepted by both: nothing, defaults, a module's settings beside another's (the absent one keeps its defaults).
  for (const std::string yaml :
       {"", "estimator: {window_s: 0.5}\n", "slam:\n  backend: 2d\n  2d: {keyframe_distance: 0.5}\n"}) {
    const Verdicts v = judge(dir, yaml, all);
    EXPECT_EQ(v.check, "") << yaml;
    EXPECT_EQ(v.make, "") << yaml;
  }
  // Refused by both, with the same line.
  for (const std::string yaml : {
           "[1, 2]\n",                           // not a map
           "estimater: {window_s: 0.5}\n",       // no such module
           "estimator: {window_s: oops}\n",      // not a number
           "estimator: {window_s: -1}\n",        // out of range
           "slam: {backnd: 2d}\n",               // no such key
           "slam:\n  2d: {ini: nowhere.ini}\n",  // a file it names, missing
           "controller: {scenario: [1, 2]}\n",   // not a file name
           "controller: {route: [[0, 0]]}\n",    // a route of one point
           "flight: {vehicle: {mass: -2}}\n",
           "estimator: {window_s: {a: 1}}\n",  // a map where a number goes
       }) {
    const Verdicts v = judge(dir, yaml, all);
    EXPECT_NE(v.check, "") << yaml;
    EXPECT_EQ(v.check, v.make) << yaml;
    EXPECT_EQ(v.check.rfind(dir.file("modules.yaml"), 0), 0u) << v.check;  // names the file
  }
  // Only the modules asked for are checked, as only they are made.
  const Verdicts v = judge(dir, "estimator: {window_s: oops}\n", "slam");
  EXPECT_EQ(v.check, "");
  EXPECT_EQ(v.make, "");
  EXPECT_EQ(judge(dir, "", "slam,nope").check, "--modules: unknown module 'nope' (known: " + known_modules() + ")");
}

TEST(ModuleSettings, TextNamesItsOriginAndTheReferenceListsEveryModuleInOrder) {
  auto s = parse_module_settings("estimator:\n  window_s: oops\n", "settings");
  ASSERT_TRUE(s) << s.error().message;
  const Status st = check_module_settings(*s, "estimator");
  ASSERT_FALSE(st);
  EXPECT_EQ(st.message().rfind("settings:2: estimator.window_s", 0), 0u) << st.message();
  EXPECT_FALSE(parse_module_settings("a: [", "settings"));

  const std::string ref = config_reference();
  size_t at = 0;
  for (const auto& k : kModuleKinds) {
    const size_t found = ref.find("### " + std::string(k.name) + "\n", at);
    ASSERT_NE(found, std::string::npos) << k.name;
    at = found;
  }
  EXPECT_NE(ref.find("estimator.window_s"), std::string::npos);
}

}  // namespace
}  // namespace driftlab::modules
