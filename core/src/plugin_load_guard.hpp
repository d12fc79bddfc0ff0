// A plugin's own start-up code (its static constructors, and the entry point lodestone calls
// first) runs inside the process before the loader can check anything about it. When that code
// crashes, the process dies with a bare "Segmentation fault" and nothing says which of the
// files in the plugin path did it. While a PluginLoadGuard lives, a fatal signal on the loading
// thread first writes one line naming the plugin file, then goes on to whatever handled the
// signal before (the crash guard of a running pipeline drives its outputs safe; otherwise the
// default action ends the process, with a core dump where enabled).
//
// Guards serialise: one plugin is loaded at a time in a process (dlopen() takes its own global
// lock anyway).
#pragma once

#include <mutex>
#include <string>

namespace lode::detail {

class PluginLoadGuard {
 public:
  explicit PluginLoadGuard(const std::string& plugin_file);
  ~PluginLoadGuard();
  PluginLoadGuard(const PluginLoadGuard&) = delete;
  PluginLoadGuard& operator=(const PluginLoadGuard&) = delete;

 private:
  std::unique_lock<std::mutex> serialised_;
};

}  // namespace lode::detail
