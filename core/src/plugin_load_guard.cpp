#include "plugin_load_guard.hpp"

#include <signal.h>
#include <string.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>

#include "fatal_signals.hpp"

namespace lode::detail {

namespace {

std::mutex g_loading;
// Written under g_loading before the handlers are installed; read only by the handler.
char g_plugin_file[4096];
std::atomic<long> g_loading_thread{0};
struct sigaction g_previous[kFatalSignalCount];

long this_thread_id() noexcept { return static_cast<long>(::syscall(SYS_gettid)); }

extern "C" void on_fatal_signal_while_loading(int sig, siginfo_t* /*info*/, void* /*context*/) {
  // Another thread's crash (the RT thread of a running pipeline during a hot swap's load) is not
  // this plugin's: say nothing about it.
  if (g_loading_thread.load() == this_thread_id()) {
    write_stderr("lode: ");
    write_stderr(signal_name(sig));
    write_stderr(" while loading the plugin ");
    write_stderr(g_plugin_file);
    write_stderr(": its own start-up code crashed, before lodestone could check it; "
                 "move the file out of the plugin path, or rebuild it against this lodestone\n");
  }
  // To whoever handled the signal before: raised now, it is delivered when this handler returns
  // (a faulting instruction would fault again anyway).
  for (std::size_t i = 0; i < kFatalSignalCount; ++i)
    if (kFatalSignals[i] == sig) (void)::sigaction(sig, &g_previous[i], nullptr);
  (void)::raise(sig);
}

}  // namespace

PluginLoadGuard::PluginLoadGuard(const std::string& plugin_file) : serialised_(g_loading) {
  const std::size_t n = std::min(plugin_file.size(), sizeof g_plugin_file - 1);
  ::memcpy(g_plugin_file, plugin_file.data(), n);
  g_plugin_file[n] = '\0';
  g_loading_thread.store(this_thread_id());
  for (std::size_t i = 0; i < kFatalSignalCount; ++i) {
    struct sigaction sa {};
    sa.sa_sigaction = on_fatal_signal_while_loading;
    sa.sa_flags = SA_SIGINFO | SA_ONSTACK;
    sigemptyset(&sa.sa_mask);
    (void)::sigaction(kFatalSignals[i], &sa, &g_previous[i]);
  }
}

PluginLoadGuard::~PluginLoadGuard() {
  for (std::size_t i = 0; i < kFatalSignalCount; ++i) (void)::sigaction(kFatalSignals[i], &g_previous[i], nullptr);
  g_loading_thread.store(0);
}

}  // namespace lode::detail
