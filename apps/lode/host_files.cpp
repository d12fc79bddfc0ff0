#include "host_files.hpp"

#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace lode::cli {

HostFiles::HostFiles(std::string root) : root_(std::move(root)) {
  while (root_.size() > 1 && root_.back() == '/') root_.pop_back();
}

std::string HostFiles::full(const std::string& path) const { return root_ == "/" ? path : root_ + path; }

std::optional<std::string> HostFiles::read(const std::string& path) const {
  std::ifstream in(full(path));
  if (!in) return std::nullopt;
  std::stringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return std::nullopt;
  auto s = ss.str();
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\t')) s.pop_back();
  return s;
}

std::vector<std::string> HostFiles::list(const std::string& dir) const {
  std::vector<std::string> names;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(full(dir), ec), end; !ec && it != end; it.increment(ec))
    names.push_back(it->path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

bool HostFiles::exists(const std::string& path) const {
  std::error_code ec;
  return std::filesystem::exists(full(path), ec);
}

bool HostFiles::writable(const std::string& path) const { return access(full(path).c_str(), W_OK) == 0; }

namespace {
std::optional<int> to_int(std::string_view s, int base = 10) {
  int v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v, base);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size() || v < 0) return std::nullopt;
  return v;
}
}  // namespace

std::optional<std::set<int>> parse_cpu_list(const std::string& text) {
  std::set<int> cpus;
  std::string_view rest = text;
  while (!rest.empty()) {
    const auto comma = rest.find(',');
    const auto item = rest.substr(0, comma);
    rest = comma == std::string_view::npos ? std::string_view{} : rest.substr(comma + 1);
    if (item.empty()) continue;
    const auto dash = item.find('-');
    const auto first = to_int(item.substr(0, dash));
    const auto last = dash == std::string_view::npos ? first : to_int(item.substr(dash + 1));
    if (!first || !last || *last < *first || *last > 65535) return std::nullopt;
    for (int c = *first; c <= *last; ++c) cpus.insert(c);
  }
  return cpus;
}

std::string format_cpu_list(const std::set<int>& cpus) {
  std::string out;
  for (auto it = cpus.begin(); it != cpus.end();) {
    int first = *it, last = *it;
    while (++it != cpus.end() && *it == last + 1) last = *it;
    if (!out.empty()) out += ',';
    out += std::to_string(first);
    if (last != first) out += '-' + std::to_string(last);
  }
  return out;
}

std::optional<std::set<int>> parse_cpu_mask(const std::string& text) {
  std::string hex;
  for (const char c : text)
    if (c != ',') hex += c;
  if (hex.empty()) return std::nullopt;
  std::set<int> cpus;
  int bit = 0;
  for (auto it = hex.rbegin(); it != hex.rend(); ++it, bit += 4) {
    const auto nibble = to_int(std::string_view(&*it, 1), 16);
    if (!nibble) return std::nullopt;
    for (int b = 0; b < 4; ++b)
      if ((*nibble >> b) & 1) cpus.insert(bit + b);
  }
  return cpus;
}

std::string format_cpu_mask(const std::set<int>& cpus) {
  if (cpus.empty()) return "0";
  const int top = *cpus.rbegin();
  std::string hex;
  for (int base = 0; base <= top; base += 4) {
    int nibble = 0;
    for (int b = 0; b < 4; ++b)
      if (cpus.count(base + b)) nibble |= 1 << b;
    hex.insert(hex.begin(), "0123456789abcdef"[nibble]);
  }
  return hex;
}

namespace {
std::vector<std::string> words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

/// One soft limit of /proc/self/limits ("Max realtime priority  0  0"); nullopt = unlimited.
std::optional<std::optional<std::uint64_t>> soft_limit(const std::string& limits, const std::string& label) {
  std::istringstream in(limits);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(label, 0) != 0) continue;
    const auto w = words(line.substr(label.size()));
    if (w.empty()) return std::nullopt;
    if (w[0] == "unlimited") return std::optional<std::uint64_t>{};
    std::uint64_t v = 0;
    const auto [end, ec] = std::from_chars(w[0].data(), w[0].data() + w[0].size(), v);
    if (ec != std::errc() || end != w[0].data() + w[0].size()) return std::nullopt;
    return std::optional<std::uint64_t>{v};
  }
  return std::nullopt;
}
}  // namespace

ProcessFacts read_process_facts(const HostFiles& files) {
  ProcessFacts f;
  if (const auto status = files.read("/proc/self/status")) {
    std::istringstream in(*status);
    bool uid_seen = false;
    for (std::string line; std::getline(in, line);) {
      const auto w = words(line);
      if (w.empty()) continue;
      if (w[0] == "Uid:" && w.size() >= 3) {
        // The effective uid decides what the kernel allows this process.
        uid_seen = std::from_chars(w[2].data(), w[2].data() + w[2].size(), f.uid).ec == std::errc();
      } else if (w[0] == "Groups:") {
        for (std::size_t i = 1; i < w.size(); ++i) {
          std::uint32_t g = 0;
          if (std::from_chars(w[i].data(), w[i].data() + w[i].size(), g).ec == std::errc()) f.groups.push_back(g);
        }
      } else if (w[0] == "CapEff:" && w.size() >= 2) {
        std::from_chars(w[1].data(), w[1].data() + w[1].size(), f.effective_caps, 16);
      }
    }
    f.known = uid_seen;
  }
  if (const auto limits = files.read("/proc/self/limits")) {
    const auto rtprio = soft_limit(*limits, "Max realtime priority");
    const auto memlock = soft_limit(*limits, "Max locked memory");
    if (rtprio && memlock) {
      f.limits_known = true;
      // An unlimited RLIMIT_RTPRIO allows every priority.
      f.rtprio_limit = rtprio->value_or(99);
      f.memlock_limit = *memlock;
    }
  }
  return f;
}

}  // namespace lode::cli
