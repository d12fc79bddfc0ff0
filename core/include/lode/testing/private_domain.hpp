// A DDS domain id that no other test process on this host is using. Each candidate id has a
// lock file under /tmp/lode-test-domains; the first one this process can lock exclusively
// (flock, released when the process exits, even on a crash) is its domain. The search starts
// at an offset derived from the process id, so concurrent tests rarely even contend. A domain
// some other process is using (another user's `lode run`, any Fast DDS participant: its
// discovery ports are bound) is passed over even when its lock file is free.
#pragma once

namespace lode::testing {

/// The same id for the whole process (taken on the first call). Ids 100-229: below 100 are the
/// domains people pick by hand, and Fast DDS's port mapping ends at 232.
/// Says which on stderr, so that a failing test names its domain.
int private_dds_domain();
/// One more such domain, different from every other this process holds (a test that needs two).
int another_private_dds_domain();

}  // namespace lode::testing
