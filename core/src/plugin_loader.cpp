#include "lode/plugin_loader.hpp"

#include <dlfcn.h>
#include <elf.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <set>

#include "lode/nearest_name.hpp"
#include "plugin_load_guard.hpp"

namespace fs = std::filesystem;

namespace lode {

namespace {
constexpr const char* kFilePrefix = "lode-";
constexpr const char* kFileSuffix = ".so";

std::string executable_dir() {
  std::error_code ec;
  const auto exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : exe.parent_path().string();
}
/// What dlopen() cannot be trusted with: it blocks for ever opening a FIFO, and maps a
/// truncated library (an interrupted copy or install) whole, so that the first touch of the
/// missing part kills the process with SIGBUS. A regular file whose loadable segments all
/// lie within it passes; anything that is not a 64-bit ELF file is left to dlopen(), which
/// says what it is.
Status check_shared_object(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return {};  // dlopen() says why it cannot be opened
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) return {};
  if (!S_ISREG(st.st_mode))
    return Status::error("cannot load plugin file " + path + ": not a regular file (a FIFO, device or socket)");
  Elf64_Ehdr header{};
  if (::pread(fd, &header, sizeof header, 0) != static_cast<ssize_t>(sizeof header) ||
      std::memcmp(header.e_ident, ELFMAG, SELFMAG) != 0 || header.e_ident[EI_CLASS] != ELFCLASS64 ||
      header.e_phentsize != sizeof(Elf64_Phdr)) {
    return {};
  }
  const auto size = static_cast<std::uint64_t>(st.st_size);
  const auto truncated = [&](std::uint64_t needed) {
    return Status::error("cannot load plugin file " + path + ": truncated: its ELF headers need " +
                         std::to_string(needed) + " bytes and the file has " + std::to_string(size) +
                         " (an interrupted copy or install? copy it again)");
  };
  const std::uint64_t headers_end = header.e_phoff + std::uint64_t{header.e_phnum} * sizeof(Elf64_Phdr);
  if (headers_end > size) return truncated(headers_end);
  for (unsigned i = 0; i < header.e_phnum; ++i) {
    Elf64_Phdr segment{};
    if (::pread(fd, &segment, sizeof segment, static_cast<off_t>(header.e_phoff + i * sizeof(Elf64_Phdr))) !=
        static_cast<ssize_t>(sizeof segment)) {
      return truncated(headers_end);
    }
    if ((segment.p_type == PT_LOAD || segment.p_type == PT_DYNAMIC) && segment.p_offset + segment.p_filesz > size)
      return truncated(segment.p_offset + segment.p_filesz);
  }
  return {};
}

}  // namespace

std::vector<std::string> PluginRegistry::default_search_path() {
  std::vector<std::string> path;
  if (const char* env = std::getenv("LODE_PLUGIN_PATH")) {
    std::string s(env);
    std::size_t start = 0;
    while (start <= s.size()) {
      const auto end = s.find(':', start);
      const auto item = s.substr(start, end == std::string::npos ? std::string::npos : end - start);
      if (!item.empty()) path.push_back(item);
      if (end == std::string::npos) break;
      start = end + 1;
    }
  }
  // Relative to the running program, so an installed tree works from whatever prefix it was
  // unpacked into and no folder of the build machine is compiled in: first where the install
  // puts the plugins beside the program's bin folder, then the build tree's layout (programs
  // in build/apps, plugins in build/plugins).
  const auto exe_dir = executable_dir();
  if (!exe_dir.empty()) {
    path.push_back(exe_dir + "/" LODE_PLUGIN_DIR_FROM_BINDIR);
    path.push_back(exe_dir + "/../plugins");
  }
  return path;
}

PluginRegistry::PluginRegistry(std::vector<std::string> search_path)
    : search_path_(std::move(search_path)) {}

Expected<LoadedPlugin> PluginRegistry::load_file(const std::string& path) {
  {
    std::lock_guard lock(mutex_);
    if (auto it = by_path_.find(path); it != by_path_.end()) return it->second;
  }
  if (Status usable = check_shared_object(path); !usable) return usable;
  const PluginDescriptor* d = nullptr;
  {
    // The plugin's static constructors run in dlopen(), its entry point just after: a crash in
    // either names the file.
    detail::PluginLoadGuard guard(path);
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      const char* why = dlerror();
      return Status::error("cannot load plugin file " + path + ": " + (why ? why : "unknown dlopen error"));
    }
    dlerror();
    void* symbol = dlsym(handle, kPluginSymbol);
    if (!symbol) {
      return Status::error(path + " is not a lodestone plugin: it does not export the symbol '" +
                           std::string(kPluginSymbol) + "' (use the LODE_PLUGIN macro)");
    }
    d = reinterpret_cast<PluginEntry>(symbol)();
  }
  if (!d) return Status::error(path + ": " + kPluginSymbol + "() returned null");
  if (d->abi_version != kPluginAbiVersion || d->descriptor_size != sizeof(PluginDescriptor)) {
    return Status::error(path + ": plugin ABI version " + std::to_string(d->abi_version) +
                         " (descriptor " + std::to_string(d->descriptor_size) +
                         " bytes) does not match this lodestone's ABI version " +
                         std::to_string(kPluginAbiVersion) + " (" +
                         std::to_string(sizeof(PluginDescriptor)) +
                         " bytes): rebuild the plugin against this SDK");
  }
  if (!d->name || !d->create) return Status::error(path + ": descriptor has no name or create()");
  LoadedPlugin loaded{d, path};
  std::lock_guard lock(mutex_);
  by_path_[path] = loaded;
  by_name_.emplace(d->name, loaded);
  return loaded;
}

Expected<LoadedPlugin> PluginRegistry::find(const std::string& name) {
  {
    std::lock_guard lock(mutex_);
    if (auto it = by_name_.find(name); it != by_name_.end()) return it->second;
  }
  const std::string file = kFilePrefix + name + kFileSuffix;
  for (const auto& dir : search_path_) {
    const fs::path candidate = fs::path(dir) / file;
    std::error_code ec;
    if (!fs::is_regular_file(candidate, ec)) continue;
    auto loaded = load_file(candidate.string());
    if (!loaded) return loaded;
    if (std::string(loaded->descriptor->name) != name) {
      return Status::error(candidate.string() + " declares the name '" +
                           loaded->descriptor->name + "', expected '" + name + "'");
    }
    return loaded;
  }
  std::string searched;
  std::vector<std::string> installed;  // the names of the plugin files there, for a typo's hint
  for (const auto& dir : search_path_) {
    searched += (searched.empty() ? "" : ":") + dir;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(dir, ec)) {
      const std::string f = entry.path().filename().string();
      const std::size_t prefix = std::strlen(kFilePrefix), suffix = std::strlen(kFileSuffix);
      if (f.size() > prefix + suffix && f.rfind(kFilePrefix, 0) == 0 && f.compare(f.size() - suffix, suffix, kFileSuffix) == 0)
        installed.push_back(f.substr(prefix, f.size() - prefix - suffix));
    }
  }
  const std::string near = nearest_name(installed, name);
  return Status::error("no plugin named '" + name + "'" + (near.empty() ? "" : " (did you mean '" + near + "'?)") +
                       " (looked for " + file + " in " + searched + ")");
}

PluginRegistry::Listing PluginRegistry::discover_all() {
  Listing out;
  std::set<std::string> seen;
  for (const auto& dir : search_path_) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) continue;
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(dir, ec)) {
      const auto name = entry.path().filename().string();
      if (name.rfind(kFilePrefix, 0) == 0 && name.size() > 3 &&
          name.substr(name.size() - 3) == kFileSuffix)
        files.push_back(entry.path());
    }
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      auto loaded = load_file(f.string());
      if (!loaded) {
        out.errors.push_back(loaded.error());
        continue;
      }
      if (seen.insert(loaded->descriptor->name).second) out.plugins.push_back(*loaded);
    }
  }
  return out;
}

}  // namespace lode
