// The Unix-socket plumbing shared by the local command server (local_control.cpp) and its
// clients (local_client.cpp).
#pragma once

#include <sys/socket.h>
#include <sys/un.h>

#include <optional>
#include <string>

#include "lode/sdk/status.hpp"

namespace lode::cli::local_socket {

std::string errno_text(int e);

/// The sockaddr of `path`; false (with the reason) when it is too long for a Unix socket.
bool fill_address(const std::string& path, sockaddr_un& addr, std::string& error);

/// The directory exists (created 0700 if not, parents too: a test may point XDG_RUNTIME_DIR
/// at a fresh path), is a real directory, ours, and private.
Status ensure_private_dir(const std::string& dir);

/// SO_PEERCRED of a connected Unix socket.
std::optional<ucred> peer_of(int fd);

/// Nonblocking connect; 0 = connected, else errno. EAGAIN: the backlog is full (it lives).
int connect_unix(const std::string& path, int& fd);

}  // namespace lode::cli::local_socket
