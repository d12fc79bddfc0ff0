// Shipped pipelines as text, edited for one test: the fixture helpers the integration tests
// share.
#pragma once

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <sstream>
#include <string>

namespace lode::test {

/// The whole text of a file (empty if it cannot be read: the load that follows says so).
inline std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// An edited YAML tree as the text a pipeline is loaded from.
inline std::string emit(const YAML::Node& root) {
  YAML::Emitter out;
  out << root;
  return out.c_str();
}

/// config/NAME of the source tree.
inline std::string read_config(const std::string& name) {
  return read_file(std::string(LODE_SOURCE_DIR) + "/config/" + name);
}

/// `text` with the first `from` replaced by `to`. A `from` that is gone (the shipped file
/// changed) fails the test that asked, rather than testing an unedited pipeline.
inline std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << "test fixture: '" << from << "' not in the config";
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

}  // namespace lode::test
