// The loader refuses what is not a plugin, or a plugin of another ABI, with a clear message.
#include <cstdlib>
#include <gtest/gtest.h>

#include "lode/sdk/testing/block_host.hpp"
#include "lode/plugin_loader.hpp"

namespace {

TEST(PluginLoader, MissingSymbolIsNamed) {
  lode::PluginRegistry reg(std::vector<std::string>{});
  auto r = reg.load_file(LODE_BAD_PLUGIN_DIR "/lode-test.no_symbol.so");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("is not a lodestone plugin: it does not export the symbol 'lode_plugin_descriptor'"),
            std::string::npos)
      << r.error();
}

TEST(PluginLoader, AbiMismatchNamesBothVersions) {
  lode::PluginRegistry reg(std::vector<std::string>{});
  auto r = reg.load_file(LODE_BAD_PLUGIN_DIR "/lode-test.wrong_abi.so");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("plugin ABI version " + std::to_string(lode::kPluginAbiVersion + 1)),
            std::string::npos) << r.error();
  EXPECT_NE(r.error().find("does not match this lodestone's ABI version " + std::to_string(lode::kPluginAbiVersion)),
            std::string::npos) << r.error();
  EXPECT_NE(r.error().find("rebuild the plugin"), std::string::npos);
}

TEST(PluginLoader, APluginBuiltForTheLastAbiIsRefusedNamingBothVersions) {
  lode::PluginRegistry reg(std::vector<std::string>{});
  auto r = reg.load_file(LODE_BAD_PLUGIN_DIR "/lode-test.old_abi.so");
  ASSERT_FALSE(r);
  EXPECT_EQ(lode::kPluginAbiVersion, 5u) << "a new ABI: give this test plugin the one before";
  EXPECT_NE(r.error().find("plugin ABI version 4"), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("does not match this lodestone's ABI version 5"), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("rebuild the plugin against this SDK"), std::string::npos) << r.error();
}

TEST(PluginLoader, APortOutsideThePortTableOrOneLeftOutIsRefused) {
  ::setenv("LODE_PLUGIN_PATH", LODE_BAD_PLUGIN_DIR, 1);
  lode::BlockHost h("test.undeclared_port", "", 100.0);
  ::unsetenv("LODE_PLUGIN_PATH");
  ASSERT_FALSE(h.configure());
  const std::string why = h.diagnostics();
  EXPECT_NE(why.find("declared output 'out' that its port table does not list"), std::string::npos) << why;
  EXPECT_NE(why.find("did not declare output 'value'"), std::string::npos) << why;
}

TEST(PluginLoader, UnknownNameListsTheSearchPath) {
  lode::PluginRegistry reg({"/nonexistent/a", "/nonexistent/b"});
  auto r = reg.find("estimator.nothing");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("no plugin named 'estimator.nothing' (looked for lode-estimator.nothing.so in "
                           "/nonexistent/a:/nonexistent/b)"),
            std::string::npos) << r.error();
}

TEST(PluginLoader, FindsShippedPluginsFromTheDefaultPath) {
  lode::PluginRegistry reg;
  auto r = reg.find("estimator.glsdc");
  ASSERT_TRUE(r) << r.error();
  EXPECT_STREQ(r->descriptor->name, "estimator.glsdc");
  EXPECT_EQ(r->descriptor->kind, lode::PluginKind::estimator);
  const auto listing = reg.discover_all();
  EXPECT_GE(listing.plugins.size(), 10u);
}

}  // namespace
