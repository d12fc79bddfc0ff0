// The loader refuses what is not a plugin, or a plugin of another ABI, with a clear message.
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>

#include "lode/sdk/testing/block_host.hpp"
#include "lode/sdk/testing/scratch_dir.hpp"
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
  EXPECT_EQ(lode::kPluginAbiVersion, 6u) << "a new ABI: give this test plugin the one before";
  EXPECT_NE(r.error().find("plugin ABI version 5"), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("does not match this lodestone's ABI version 6"), std::string::npos) << r.error();
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

// An interrupted copy or install leaves a library shorter than its headers say; dlopen()
// maps it whole and the first touch of the missing part killed the process with SIGBUS.
TEST(PluginLoader, ATruncatedPluginIsRefusedNotACrash) {
  const std::string whole = LODE_BAD_PLUGIN_DIR "/lode-test.no_symbol.so";
  const std::string cut = lode::testing::scratch_path("lode-test.truncated.so");
  std::filesystem::copy_file(whole, cut, std::filesystem::copy_options::overwrite_existing);
  std::filesystem::resize_file(cut, 3000);
  lode::PluginRegistry reg(std::vector<std::string>{});
  auto r = reg.load_file(cut);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find(cut + ": truncated: its ELF headers need"), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("and the file has 3000"), std::string::npos) << r.error();
}

// A FIFO named like a plugin: dlopen() would wait for a writer for ever (`lode plugins` hung).
TEST(PluginLoader, AFifoNamedLikeAPluginIsRefusedNotWaitedFor) {
  const std::filesystem::path dir = lode::testing::scratch_path("fifo_plugins");
  std::filesystem::create_directories(dir);
  const std::string fifo = (dir / "lode-test.fifo.so").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  ::alarm(60);  // a hang fails the test (SIGALRM) instead of waiting for ctest's timeout
  lode::PluginRegistry reg({dir.string()});
  const auto listing = reg.discover_all();
  ::alarm(0);
  ASSERT_EQ(listing.errors.size(), 1u);
  EXPECT_NE(listing.errors[0].find(fifo + ": not a regular file"), std::string::npos) << listing.errors[0];
}

// A plugin whose static constructor crashes takes the process with it (its code runs inside
// dlopen()), but the last line on stderr names the file, so the user knows which one to remove.
TEST(PluginLoaderDeathTest, APluginThatCrashesWhileLoadingIsNamed) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const std::string crashing = LODE_BAD_PLUGIN_DIR "/lode-test.crashes_at_load.so";
  EXPECT_EXIT(
      {
        lode::PluginRegistry reg(std::vector<std::string>{});
        (void)reg.load_file(crashing);
      },
      ::testing::KilledBySignal(SIGSEGV),
      "lode: SIGSEGV while loading the plugin " + crashing + ": its own start-up code crashed");
}

extern "C" void test_segv_handler(int) {}

// After a load, the process's handlers for fatal signals are what they were before it (a
// running pipeline's crash guard, during a hot swap's load).
TEST(PluginLoader, LoadingLeavesTheSignalHandlersAsTheyWere) {
  struct sigaction mine {};
  mine.sa_handler = test_segv_handler;
  struct sigaction original {};
  ASSERT_EQ(::sigaction(SIGSEGV, &mine, &original), 0);
  lode::PluginRegistry reg(std::vector<std::string>{});
  (void)reg.load_file(LODE_BAD_PLUGIN_DIR "/lode-test.wrong_abi.so");
  struct sigaction after {};
  ASSERT_EQ(::sigaction(SIGSEGV, &original, &after), 0);
  EXPECT_EQ(reinterpret_cast<void*>(after.sa_handler), reinterpret_cast<void*>(test_segv_handler));
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
