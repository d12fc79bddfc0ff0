// What a test needs before it can say anything: plugins and tools. In the complete test
// build (every plugin, every tool installed, as setup.sh makes it) a missing one is a
// failure that names it; a skip is left only where the build was asked to be partial
// (LODE_PLUGINS) or to tolerate missing tools (LODE_REQUIRE_TEST_TOOLS=OFF), and it says why.
//
//   TEST(Seed002, ...) {
//     LODE_REQUIRE_PLUGINS("plant.suspension", "sensor.hall_gap");
//     ...
//   }
#pragma once

#include <initializer_list>
#include <string>
#include <string_view>

namespace lode::testing {

/// Folder the tests load plugins from: $LODE_PLUGIN_PATH (its first entry), else the build
/// tree's plugin folder.
std::string plugin_folder();

/// True when lode-NAME.so is in plugin_folder().
bool plugin_built(std::string_view name);

/// The names among `names` that are not built, comma-separated; empty when all are.
std::string missing_plugins(std::initializer_list<std::string_view> names);

/// True when this build was configured with a subset of the plugins (LODE_PLUGINS).
bool partial_plugin_build() noexcept;

/// The LODE_PLUGINS regex this build was configured with (empty: all).
const char* plugin_selection() noexcept;

/// True when a missing tool must fail a test (LODE_REQUIRE_TEST_TOOLS, the default).
bool tools_required() noexcept;

}  // namespace lode::testing

/// Fails the test when a plugin it needs is missing from a complete build; skips, saying which
/// and why, in a partial build.
#define LODE_REQUIRE_PLUGINS(...)                                                                   \
  do {                                                                                             \
    const std::string lode_missing_ = ::lode::testing::missing_plugins({__VA_ARGS__});             \
    if (!lode_missing_.empty()) {                                                                  \
      if (::lode::testing::partial_plugin_build()) {                                               \
        GTEST_SKIP() << "not built in this partial build (LODE_PLUGINS='"                         \
                     << ::lode::testing::plugin_selection() << "'): " << lode_missing_;            \
      }                                                                                            \
      GTEST_FAIL() << "plugins missing from a complete build: " << lode_missing_ << " (looked in " \
                   << ::lode::testing::plugin_folder() << ")";                                     \
    }                                                                                              \
  } while (false)

/// A tool the test needs is missing (`why` says which and how to install it): a failure in the
/// test set-up, a skip with the reason where missing tools are tolerated.
#define LODE_TOOL_MISSING(why)                                      \
  do {                                                             \
    if (::lode::testing::tools_required()) {                       \
      GTEST_FAIL() << "missing tool: " << (why);                   \
    }                                                              \
    GTEST_SKIP() << "missing tool (LODE_REQUIRE_TEST_TOOLS=OFF): " << (why); \
  } while (false)
