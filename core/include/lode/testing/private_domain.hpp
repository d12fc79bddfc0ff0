// A DDS domain id that no other test process on this host is using. Each candidate id has a
// lock file under /tmp/lode-test-domains; the first one this process can lock exclusively
// (flock, released when the process exits, even on a crash) is its domain. The search starts
// at an offset derived from the process id, so concurrent tests rarely even contend.
#pragma once

namespace lode::testing {

/// The same id for the whole process (taken on the first call). Ids 100-229: below 100 are the
/// domains people pick by hand, and Fast DDS's port mapping ends at 232.
int private_dds_domain();

}  // namespace lode::testing
