#include "lode/hal/analog.hpp"

#include <cmath>
#include <limits>
#include <sstream>

namespace lode::hal {

const char* to_string(Coding coding) noexcept {
  switch (coding) {
    case Coding::twos_complement: return "twos_complement";
    case Coding::offset_binary: return "offset_binary";
    case Coding::unipolar: return "unipolar";
  }
  return "?";
}

namespace {
std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}
}  // namespace

Status validate(const AnalogChannel& c) {
  const std::string who = "channel '" + c.name + "': ";
  if (c.name.empty()) return Status::error("channel: name must not be empty");
  if (c.bits < 2 || c.bits > 32) return Status::error(who + "bits must be within 2 ... 32, got " + std::to_string(c.bits));
  if (!std::isfinite(c.span_min_v) || !std::isfinite(c.span_max_v) || !(c.span_max_v > c.span_min_v))
    return Status::error(who + "span_v must be [min, max] with min < max, got [" + number(c.span_min_v) + ", " +
                         number(c.span_max_v) + "]");
  if (c.coding == Coding::unipolar && c.span_min_v < 0.0)
    return Status::error(who + "a unipolar converter spans [0, max] or above, got min " + number(c.span_min_v) + " V");
  if (!std::isfinite(c.gain) || c.gain == 0.0) return Status::error(who + "gain must be finite and non-zero, got " + number(c.gain));
  if (!std::isfinite(c.offset)) return Status::error(who + "offset must be finite");
  if (!std::isfinite(c.safe_value)) return Status::error(who + "safe_value must be finite");
  const double safe_v = (c.safe_value - c.offset) / c.gain;
  if (safe_v < c.span_min_v || safe_v > c.span_max_v)
    return Status::error(who + "safe_value " + number(c.safe_value) + " " + c.unit + " (" + number(safe_v) +
                         " V) is outside the converter's range [" + number(c.span_min_v) + ", " + number(c.span_max_v) +
                         "] V: it could not be driven");
  return {};
}

AnalogConversion::AnalogConversion(const AnalogChannel& c) noexcept
    : coding_(c.coding),
      bits_(c.bits),
      mask_(c.bits >= 32 ? 0xffffffffu : ((1u << c.bits) - 1u)),
      span_min_v_(c.span_min_v),
      lsb_v_((c.span_max_v - c.span_min_v) / std::ldexp(1.0, c.bits)),
      gain_(c.gain),
      offset_(c.offset) {
  const std::int64_t codes = std::int64_t{1} << c.bits;
  if (coding_ == Coding::unipolar) {
    k_min_ = 0;
    k_max_ = codes - 1;
  } else {
    k_min_ = -(codes / 2);
    k_max_ = codes / 2 - 1;
  }
  bool clipped = false;
  safe_code_ = value_to_code(c.safe_value, clipped);
}

std::int64_t AnalogConversion::index_of(std::uint32_t raw) const noexcept {
  const std::uint32_t field = raw & mask_;
  switch (coding_) {
    case Coding::twos_complement: {
      const std::uint32_t sign = 1u << (bits_ - 1);
      return (field & sign) ? static_cast<std::int64_t>(field) - (std::int64_t{1} << bits_) : static_cast<std::int64_t>(field);
    }
    case Coding::offset_binary: return static_cast<std::int64_t>(field) - (std::int64_t{1} << (bits_ - 1));
    case Coding::unipolar: return static_cast<std::int64_t>(field);
  }
  return 0;
}

std::uint32_t AnalogConversion::raw_of(std::int64_t k) const noexcept {
  switch (coding_) {
    case Coding::twos_complement: return static_cast<std::uint32_t>(k) & mask_;
    case Coding::offset_binary: return static_cast<std::uint32_t>(k + (std::int64_t{1} << (bits_ - 1))) & mask_;
    case Coding::unipolar: return static_cast<std::uint32_t>(k) & mask_;
  }
  return 0;
}

double AnalogConversion::code_to_value(std::uint32_t raw) const noexcept {
  const double volts = span_min_v_ + static_cast<double>(index_of(raw) - k_min_) * lsb_v_;
  return gain_ * volts + offset_;
}

std::uint32_t AnalogConversion::value_to_code(double value, bool& clipped) const noexcept {
  if (!std::isfinite(value)) {
    clipped = true;
    return safe_code_;
  }
  const double volts = (value - offset_) / gain_;
  const double k = std::floor((volts - span_min_v_) / lsb_v_ + 0.5) + static_cast<double>(k_min_);
  if (k < static_cast<double>(k_min_)) {
    clipped = true;
    return raw_of(k_min_);
  }
  if (k > static_cast<double>(k_max_)) {
    clipped = true;
    return raw_of(k_max_);
  }
  return raw_of(static_cast<std::int64_t>(k));
}

}  // namespace lode::hal
