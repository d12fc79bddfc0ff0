#include "regmap.hpp"

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <vector>

#include "lode/hal/register_window.hpp"  // hal::hex

namespace lode::vme {

Layout Layout::default_layout() {
  Layout l;
  l.window = 0x400;
  l.board_id = 0x000;
  l.control = 0x004;
  l.status = 0x008;
  l.channels = 0x00c;
  l.trigger = 0x010;
  l.dac_load = 0x014;
  l.reset_errors = 0x018;
  l.adc_data = {0x100, 64, 4};
  l.dac_data = {0x200, 64, 4};
  l.board_id_value = 0x61020000u;  // "6102" in the high half, the revision in the low byte
  l.board_id_mask = 0xffff0000u;
  l.enable = 1u << 0;
  l.ext_trigger = 1u << 2;
  l.done = 1u << 0;
  l.busy = 1u << 1;
  l.err_overrun = 1u << 8;
  l.err_adc = 1u << 9;
  l.err_dac = 1u << 10;
  l.err_bus = 1u << 11;
  l.sequence = {16, 31};
  l.adc_channels = {0, 7};
  l.dac_channels = {8, 15};
  return l;
}

namespace {

constexpr std::size_t kMaxErrors = 20;     // a file of garbage gives a readable message
constexpr std::size_t kMaxNameLength = 64;

using hal::hex;

/// Arbitrary input bytes, made printable and short for a message.
std::string quoted(std::string_view s) {
  std::string out = "'";
  for (std::size_t i = 0; i < s.size() && i < 32; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (s.size() > 32) out += "...";
  return out + "'";
}

bool is_name(std::string_view s) {
  if (s.empty() || s.size() > kMaxNameLength) return false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    const bool alpha = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || c == '_';
    if (!alpha && !(i > 0 && c >= '0' && c <= '9')) return false;
  }
  return true;
}

/// Decimal or 0x hex, at most 0xffffffff: digits are accumulated in 64 bits and checked
/// after each one, so no input overflows.
bool parse_u32(std::string_view s, std::uint32_t& out) {
  unsigned base = 10;
  if (s.size() > 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) {
    base = 16;
    s.remove_prefix(2);
  }
  if (s.empty()) return false;
  std::uint64_t v = 0;
  for (const char c : s) {
    unsigned d = 0;
    if (c >= '0' && c <= '9') d = static_cast<unsigned>(c - '0');
    else if (base == 16 && c >= 'a' && c <= 'f') d = static_cast<unsigned>(c - 'a' + 10);
    else if (base == 16 && c >= 'A' && c <= 'F') d = static_cast<unsigned>(c - 'A' + 10);
    else return false;
    if (d >= base) return false;
    v = v * base + d;
    if (v > 0xffffffffull) return false;
  }
  out = static_cast<std::uint32_t>(v);
  return true;
}

enum class Access { ro, wo, rw };
const char* to_string(Access a) { return a == Access::ro ? "ro" : a == Access::wo ? "wo" : "rw"; }

struct RegisterDecl {
  std::string name;
  std::size_t line = 0;
  std::uint32_t offset = 0;
  Access access = Access::ro;
  bool has_value = false, is_array = false;
  std::uint32_t value = 0, mask = 0xffffffffu, count = 1, stride = 4;
  bool placed = false;  ///< aligned and inside the window: takes part in the overlap check
};

struct BitDecl {
  std::string reg, name;
  std::size_t line = 0;
  unsigned lo = 0, hi = 0;
  bool field = false;
  bool valid = false;  ///< range fine and on a known register
};

class Errors {
 public:
  explicit Errors(const std::string& file) : file_(file) {}
  void add(std::size_t line, const std::string& field, const std::string& message) {
    if (count_++ >= kMaxErrors) return;
    if (!text_.empty()) text_ += '\n';
    text_ += file_ + ":" + std::to_string(line) + ": " + field + ": " + message;
  }
  [[nodiscard]] bool empty() const { return count_ == 0; }
  [[nodiscard]] std::string message() const {
    return count_ > kMaxErrors ? text_ + "\n(" + std::to_string(count_ - kMaxErrors) + " more problems)" : text_;
  }

 private:
  const std::string& file_;
  std::string text_;
  std::size_t count_ = 0;
};

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

// What io.vme_pentek needs: each register with the host's access to it.
struct Required {
  const char* name;
  bool array, read, write;
  std::size_t Layout::*offset;    // single registers
  RegisterArray Layout::*array_;  // arrays
};
constexpr Required kRequiredRegisters[] = {
    {"BOARD_ID", false, true, false, &Layout::board_id, nullptr},
    {"CONTROL", false, false, true, &Layout::control, nullptr},
    {"STATUS", false, true, false, &Layout::status, nullptr},
    {"CHANNELS", false, true, false, &Layout::channels, nullptr},
    {"TRIGGER", false, true, true, &Layout::trigger, nullptr},    // set, then read back on a timeout
    {"DAC_LOAD", false, true, true, &Layout::dac_load, nullptr},  // set, then checked next cycle
    {"RESET_ERRORS", false, false, true, &Layout::reset_errors, nullptr},
    {"ADC_DATA", true, true, false, nullptr, &Layout::adc_data},
    {"DAC_DATA", true, false, true, nullptr, &Layout::dac_data},
};

struct RequiredBit {
  const char* reg;
  const char* name;
  std::uint32_t Layout::*bit;  // a single bit, or
  BitField Layout::*field;     // a field of any width
};
constexpr RequiredBit kRequiredBits[] = {
    {"CONTROL", "ENABLE", &Layout::enable, nullptr},
    {"CONTROL", "EXT_TRIGGER", &Layout::ext_trigger, nullptr},
    {"STATUS", "DONE", &Layout::done, nullptr},
    {"STATUS", "BUSY", &Layout::busy, nullptr},
    {"STATUS", "ERR_OVERRUN", &Layout::err_overrun, nullptr},
    {"STATUS", "ERR_ADC", &Layout::err_adc, nullptr},
    {"STATUS", "ERR_DAC", &Layout::err_dac, nullptr},
    {"STATUS", "ERR_BUS", &Layout::err_bus, nullptr},
    {"STATUS", "SEQUENCE", nullptr, &Layout::sequence},
    {"CHANNELS", "ADC", nullptr, &Layout::adc_channels},
    {"CHANNELS", "DAC", nullptr, &Layout::dac_channels},
};

const char* const kRegisterUsage = "expected: register NAME OFFSET ro|wo|rw [value V] [mask M] [count N] [stride S]";

}  // namespace

Expected<Layout> parse_layout(std::string_view text, const std::string& file) {
  Errors errors(file);
  std::vector<RegisterDecl> registers;
  std::vector<BitDecl> bits;
  std::uint32_t window = 0;
  std::size_t window_line = 0;
  std::size_t line_no = 0;

  // Pass 1: each line on its own (syntax, numbers, names); bits may name registers declared
  // further down, so references are resolved after the whole file is read.
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::vector<std::string_view> w = split_words(line);
    if (w.empty()) continue;
    const std::string_view directive = w[0];

    if (directive == "window") {
      std::uint32_t size = 0;
      if (w.size() != 2 || !parse_u32(w[1], size)) {
        errors.add(line_no, "window", "expected: window SIZE (bytes, decimal or 0x hex)");
      } else if (window_line != 0) {
        errors.add(line_no, "window", "duplicate (first on line " + std::to_string(window_line) + ")");
      } else if (size < 4 || size > kMaxWindow || size % 4 != 0) {
        errors.add(line_no, "window", "size " + hex(size) + " must be a multiple of 4 within 4 ... " + hex(kMaxWindow));
        window_line = line_no;
      } else {
        window = size;
        window_line = line_no;
      }
      continue;
    }

    if (directive == "register") {
      if (w.size() < 4 || !is_name(w[1])) {
        const std::string name = w.size() < 2 ? std::string() : is_name(w[1]) ? std::string(w[1]) : quoted(w[1]);
        errors.add(line_no, name.empty() ? std::string("register") : "register " + name,
                   w.size() >= 2 && !is_name(w[1]) ? "bad name (letters, digits, _)" : kRegisterUsage);
        continue;
      }
      RegisterDecl r;
      r.name = std::string(w[1]);
      r.line = line_no;
      const std::string field = "register " + r.name;
      bool ok = true;
      if (!parse_u32(w[2], r.offset)) {
        errors.add(line_no, field, "bad offset " + quoted(w[2]) + " (decimal or 0x hex, at most 0xffffffff)");
        ok = false;
      }
      if (w[3] == "ro") r.access = Access::ro;
      else if (w[3] == "wo") r.access = Access::wo;
      else if (w[3] == "rw") r.access = Access::rw;
      else {
        errors.add(line_no, field, "access " + quoted(w[3]) + " is not ro, wo or rw");
        ok = false;
      }
      bool seen_value = false, seen_mask = false, seen_count = false, seen_stride = false;
      for (std::size_t i = 4; i < w.size(); i += 2) {
        const std::string_view key = w[i];
        bool* seen = key == "value"   ? &seen_value
                     : key == "mask"  ? &seen_mask
                     : key == "count" ? &seen_count
                     : key == "stride" ? &seen_stride
                                       : nullptr;
        if (seen == nullptr) {
          errors.add(line_no, field, "unknown attribute " + quoted(key) + " (value, mask, count, stride)");
          ok = false;
          break;
        }
        if (*seen) {
          errors.add(line_no, field, "duplicate attribute " + std::string(key));
          ok = false;
          break;
        }
        *seen = true;
        std::uint32_t v = 0;
        if (i + 1 >= w.size() || !parse_u32(w[i + 1], v)) {
          errors.add(line_no, field,
                     "bad " + std::string(key) + (i + 1 < w.size() ? " " + quoted(w[i + 1]) : std::string()) +
                         " (decimal or 0x hex, at most 0xffffffff)");
          ok = false;
          break;
        }
        if (key == "value") r.value = v;
        else if (key == "mask") r.mask = v;
        else if (key == "count") r.count = v;
        else r.stride = v;
      }
      r.has_value = seen_value;
      r.is_array = seen_count || seen_stride;
      if (!ok) continue;
      if (registers.size() >= kMaxRegisters) {
        errors.add(line_no, field, "more than " + std::to_string(kMaxRegisters) + " registers");
        continue;
      }
      registers.push_back(std::move(r));
      continue;
    }

    if (directive == "bit" || directive == "field") {
      const bool is_field = directive == "field";
      const std::string kind(directive);
      const std::string usage = is_field ? "expected: field REGISTER.NAME LO..HI" : "expected: bit REGISTER.NAME BIT";
      if (w.size() != 3) {
        errors.add(line_no, w.size() >= 2 ? kind + " " + quoted(w[1]) : kind, usage);
        continue;
      }
      const std::size_t dot = w[1].find('.');
      if (dot == std::string_view::npos || !is_name(w[1].substr(0, dot)) || !is_name(w[1].substr(dot + 1))) {
        errors.add(line_no, kind + " " + quoted(w[1]), "expected REGISTER.NAME (letters, digits, _)");
        continue;
      }
      BitDecl b;
      b.reg = std::string(w[1].substr(0, dot));
      b.name = std::string(w[1].substr(dot + 1));
      b.line = line_no;
      b.field = is_field;
      const std::string field = kind + " " + b.reg + "." + b.name;
      std::uint32_t lo = 0, hi = 0;
      if (is_field) {
        const std::size_t dots = w[2].find("..");
        if (dots == std::string_view::npos || !parse_u32(w[2].substr(0, dots), lo) ||
            !parse_u32(w[2].substr(dots + 2), hi)) {
          errors.add(line_no, field, "bad bit range " + quoted(w[2]) + " (LO..HI, e.g. 16..31)");
          continue;
        }
      } else if (!parse_u32(w[2], lo)) {
        errors.add(line_no, field, "bad bit number " + quoted(w[2]));
        continue;
      } else {
        hi = lo;
      }
      if (hi > 31 || lo > 31) {
        errors.add(line_no, field,
                   (is_field ? "bits " + std::to_string(lo) + ".." + std::to_string(hi) : "bit " + std::to_string(lo)) +
                       " not within 0 ... 31 (32-bit registers)");
        continue;
      }
      if (lo > hi) {
        errors.add(line_no, field, "low bit " + std::to_string(lo) + " above high bit " + std::to_string(hi));
        continue;
      }
      b.lo = lo;
      b.hi = hi;
      if (bits.size() >= kMaxBits) {
        errors.add(line_no, field, "more than " + std::to_string(kMaxBits) + " bits and fields");
        continue;
      }
      bits.push_back(std::move(b));
      continue;
    }

    errors.add(line_no, quoted(directive), "unknown directive (window, register, bit, field)");
  }
  const std::size_t last_line = line_no == 0 ? 1 : line_no;  // where "missing" is reported

  // Pass 2: registers. Names, alignment, the window, overlaps.
  if (window_line == 0) errors.add(last_line, "window", "missing (window SIZE: the bytes the host maps)");
  std::map<std::string, std::size_t, std::less<>> register_index;  // name -> first declaration
  for (std::size_t i = 0; i < registers.size(); ++i) {
    RegisterDecl& r = registers[i];
    const std::string field = "register " + r.name;
    if (const auto [it, inserted] = register_index.emplace(r.name, i); !inserted) {
      errors.add(r.line, field, "duplicate name (first on line " + std::to_string(registers[it->second].line) + ")");
      continue;
    }
    bool ok = true;
    if (r.offset % 4 != 0) {
      errors.add(r.line, field, "offset " + hex(r.offset) + " is not a multiple of 4 (32-bit registers)");
      ok = false;
    }
    if (r.stride < 4 || r.stride % 4 != 0) {
      errors.add(r.line, field, "stride " + std::to_string(r.stride) + " is not a multiple of 4 (at least 4)");
      ok = false;
    }
    if (r.count < 1 || r.count > kMaxWindow / 4) {
      errors.add(r.line, field, "count " + std::to_string(r.count) + " not within 1 ... " + std::to_string(kMaxWindow / 4));
      ok = false;
    }
    if (r.has_value && r.is_array) {
      errors.add(r.line, field, "value/mask are for a single register, not an array");
      ok = false;
    }
    if ((r.value & ~r.mask) != 0) {
      errors.add(r.line, field, "value " + hex(r.value) + " has bits outside mask " + hex(r.mask));
      ok = false;
    }
    if (!ok || window == 0) continue;
    // count <= kMaxWindow / 4 and stride < 2^32: the end fits in 64 bits.
    const std::uint64_t end = std::uint64_t{r.offset} + std::uint64_t{r.stride} * (r.count - 1) + 4;
    if (end > window) {
      if (r.count == 1)
        errors.add(r.line, field, "offset " + hex(r.offset) + " is outside the window (" + hex(window) + " bytes)");
      else
        errors.add(r.line, field,
                   "array " + hex(r.offset) + " + " + std::to_string(r.stride) + " * " + std::to_string(r.count) +
                       " ends at " + hex(end) + ", outside the window (" + hex(window) + " bytes)");
      continue;
    }
    r.placed = true;
  }
  {
    // Which register holds each 32-bit word of the window (index + 1; 0 = free).
    std::vector<std::uint16_t> owner(window / 4, 0);
    for (std::size_t i = 0; i < registers.size(); ++i) {
      const RegisterDecl& r = registers[i];
      if (!r.placed) continue;
      for (std::uint32_t k = 0; k < r.count; ++k) {
        const std::size_t word = (std::size_t{r.offset} + std::size_t{r.stride} * k) / 4;
        if (owner[word] != 0) {
          const RegisterDecl& other = registers[owner[word] - 1u];
          errors.add(r.line, "register " + r.name,
                     "overlaps register " + other.name + " (line " + std::to_string(other.line) + ") at " + hex(word * 4));
          break;  // one report per register
        }
        owner[word] = static_cast<std::uint16_t>(i + 1);
      }
    }
  }
  auto find_register = [&](const std::string& name) -> const RegisterDecl* {
    const auto it = register_index.find(name);
    return it == register_index.end() ? nullptr : &registers[it->second];
  };

  // Pass 3: bits and fields. Known register, unique name, no shared bits within a register.
  {
    std::vector<std::array<std::int16_t, 32>> users(registers.size());  // bit -> bits[] index + 1
    std::map<std::string, std::size_t, std::less<>> bit_index;            // REG.NAME -> first declaration
    for (auto& u : users) u.fill(0);
    for (std::size_t i = 0; i < bits.size(); ++i) {
      BitDecl& b = bits[i];
      const std::string field = (b.field ? "field " : "bit ") + b.reg + "." + b.name;
      const RegisterDecl* reg = find_register(b.reg);
      if (reg == nullptr) {
        errors.add(b.line, field, "unknown register " + b.reg);
        continue;
      }
      if (const auto [it, inserted] = bit_index.emplace(b.reg + "." + b.name, i); !inserted) {
        errors.add(b.line, field, "duplicate name (first on line " + std::to_string(bits[it->second].line) + ")");
        continue;
      }
      auto& used = users[static_cast<std::size_t>(reg - registers.data())];
      bool overlap = false;
      for (unsigned k = b.lo; k <= b.hi; ++k) {
        if (used[k] != 0) {
          const BitDecl& other = bits[static_cast<std::size_t>(used[k] - 1)];
          errors.add(b.line, field,
                     "bit " + std::to_string(k) + " is also " + (other.field ? "field " : "bit ") + other.reg + "." +
                         other.name + " (line " + std::to_string(other.line) + ")");
          overlap = true;
          break;
        }
      }
      if (overlap) continue;
      for (unsigned k = b.lo; k <= b.hi; ++k) used[k] = static_cast<std::int16_t>(i + 1);
      b.valid = true;
    }
  }

  // Pass 4: what io.vme_pentek needs, with the access it needs.
  Layout layout;
  layout.window = window;
  for (const Required& req : kRequiredRegisters) {
    const std::string field = std::string("register ") + req.name;
    const RegisterDecl* r = find_register(req.name);
    if (r == nullptr) {
      errors.add(last_line, field, "missing (io.vme_pentek needs it)");
      continue;
    }
    if (req.array != r->is_array) {
      errors.add(r->line, field,
                 req.array ? "must be an array (count N [stride S]: one register per channel)"
                           : "must be a single register, not an array");
      continue;
    }
    const bool readable = r->access != Access::wo, writable = r->access != Access::ro;
    if ((req.read && !readable) || (req.write && !writable)) {
      errors.add(r->line, field,
                 std::string("access ") + to_string(r->access) + ", but the host " +
                     (req.read && req.write ? "writes and reads it (rw)"
                      : req.read            ? "reads it (ro or rw)"
                                            : "writes it (wo or rw)"));
      continue;
    }
    if (req.array) layout.*req.array_ = {r->offset, r->count, r->stride};
    else layout.*req.offset = r->offset;
  }
  if (const RegisterDecl* id = find_register("BOARD_ID"); id != nullptr) {
    if (!id->has_value) errors.add(id->line, "register BOARD_ID", "needs `value V [mask M]`: the id the host checks");
    layout.board_id_value = id->value;
    layout.board_id_mask = id->mask;
  }
  for (const RequiredBit& req : kRequiredBits) {
    const BitDecl* found = nullptr;
    bool declared = false;  // but invalid: reported above already
    for (const auto& b : bits) {
      if (b.reg != req.reg || b.name != req.name) continue;
      declared = true;
      if (b.valid) found = &b;
    }
    const std::string field = std::string(req.bit ? "bit " : "field ") + req.reg + "." + req.name;
    if (found == nullptr) {
      if (!declared) errors.add(last_line, field, "missing (io.vme_pentek needs it)");
      continue;
    }
    if (req.bit != nullptr) {
      if (found->hi != found->lo) {
        errors.add(found->line, field, "must be a single bit, not " + std::to_string(found->lo) + ".." + std::to_string(found->hi));
        continue;
      }
      layout.*req.bit = 1u << found->lo;
    } else {
      layout.*req.field = BitField{found->lo, found->hi};
    }
  }
  if (!errors.empty()) return Status::error(errors.message());
  return layout;
}

Expected<Layout> load_layout(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    return Status::error(path + ": cannot read the register map (" + (ec ? ec.message() : "not a regular file") + ")");
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) return Status::error(path + ": cannot read the register map (" + ec.message() + ")");
  if (size > kMaxMapFileBytes)
    return Status::error(path + ": " + std::to_string(size) + " bytes is too large for a register map (at most " +
                         std::to_string(kMaxMapFileBytes) + ")");
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::error(path + ": cannot open the register map");
  std::string text(static_cast<std::size_t>(size), '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  return parse_layout(text, path);
}

std::string to_text(const Layout& l) {
  std::string out = "window " + hex(l.window) + "\n";
  auto reg = [&](const char* name, std::size_t offset, const char* access) {
    out += std::string("register ") + name + " " + hex(offset) + " " + access + "\n";
  };
  out += "register BOARD_ID " + hex(l.board_id) + " ro value " + hex(l.board_id_value) + " mask " + hex(l.board_id_mask) + "\n";
  reg("CONTROL", l.control, "rw");
  reg("STATUS", l.status, "ro");
  reg("CHANNELS", l.channels, "ro");
  reg("TRIGGER", l.trigger, "rw");
  reg("DAC_LOAD", l.dac_load, "rw");
  reg("RESET_ERRORS", l.reset_errors, "rw");
  auto array = [&](const char* name, const RegisterArray& a, const char* access) {
    out += std::string("register ") + name + " " + hex(a.offset) + " " + access + " count " + std::to_string(a.count) +
           " stride " + std::to_string(a.stride) + "\n";
  };
  array("ADC_DATA", l.adc_data, "ro");
  array("DAC_DATA", l.dac_data, "rw");
  auto bit = [&](const char* name, std::uint32_t mask) {
    unsigned n = 0;
    while (n < 31 && (mask >> n) != 1u) ++n;
    out += std::string("bit ") + name + " " + std::to_string(n) + "\n";
  };
  bit("CONTROL.ENABLE", l.enable);
  bit("CONTROL.EXT_TRIGGER", l.ext_trigger);
  bit("STATUS.DONE", l.done);
  bit("STATUS.BUSY", l.busy);
  bit("STATUS.ERR_OVERRUN", l.err_overrun);
  bit("STATUS.ERR_ADC", l.err_adc);
  bit("STATUS.ERR_DAC", l.err_dac);
  bit("STATUS.ERR_BUS", l.err_bus);
  auto field = [&](const char* name, const BitField& f) {
    out += std::string("field ") + name + " " + std::to_string(f.lo) + ".." + std::to_string(f.hi) + "\n";
  };
  field("STATUS.SEQUENCE", l.sequence);
  field("CHANNELS.ADC", l.adc_channels);
  field("CHANNELS.DAC", l.dac_channels);
  return out;
}

}  // namespace lode::vme
