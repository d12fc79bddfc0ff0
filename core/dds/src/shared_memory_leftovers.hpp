// What Fast DDS processes that never closed their participant left in shared memory.
//
// Fast DDS 2.x gives every participant with the shared-memory transport a segment
// (/dev/shm/fastrtps_<16 characters>, kSharedMemorySegmentBytes, every page of it touched) and
// a port per listener (/dev/shm/fastrtps_port<N>, its queue, and sem.fastrtps_port<N>_mutex).
// A participant deleted normally removes its files. A process killed (SIGKILL, the OOM killer,
// a crash, a service manager's stop timeout) leaves them: tmpfs, that is memory, until the host
// reboots. About 8.5 MB a `lode run`, so a service that crashes and restarts all night would
// fill the host's memory with them.
//
// Each of those files has a lock file beside it (<name>_el, or _sl for a port shared by
// several listeners) that its owner keeps flock()ed for as long as it lives; the kernel drops
// the lock when the process ends, however it ends. A lock file that can be locked therefore
// belongs to a process that is gone, and `fastdds shm clean` removes such files by that rule.
// lodestone does the same when a process first creates a participant with the shared-memory
// transport, for the files of its own user (another user's are not ours to judge, and the
// sticky /dev/shm would refuse most of them anyway). Private to lodestone_dds.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace lode::dds::detail {

struct RemovedLeftovers {
  std::uint32_t segments = 0;  ///< fastrtps_<id> with its lock file
  std::uint32_t ports = 0;     ///< fastrtps_port<N> with its lock file and semaphore
  std::uint64_t bytes = 0;     ///< the memory their files held
};

/// Removes from `directory` the segments and ports whose lock file this process can lock (their
/// owner is gone) and that belong to this process's user. A lock file younger than `min_age` is
/// left alone: Fast DDS creates it and locks it in two steps.
RemovedLeftovers remove_dead_shared_memory(const std::string& directory, std::chrono::seconds min_age);

/// remove_dead_shared_memory("/dev/shm", 2 s), the first time a process calls it.
void remove_dead_shared_memory_once();

}  // namespace lode::dds::detail
