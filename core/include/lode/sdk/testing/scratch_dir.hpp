// A folder of this test process's own for the files a test writes: under the temporary
// directory, named after the process id (no other process on the host shares it), created on
// first use and removed with everything in it when the process exits, so a test run leaves
// nothing behind whatever the test does with it.
#pragma once

#include <string>

namespace lode::testing {

/// $TMPDIR/lode-test-<pid> (0700), created on first call.
const std::string& scratch_dir();
/// scratch_dir() + "/" + name.
std::string scratch_path(const std::string& name);

}  // namespace lode::testing
