#include "bank_filter.hpp"

namespace lode::plugins::filter {

StepStatus BankFilter::step(const Tick& /*tick*/) noexcept {
  const char* why = bank_.step();
  return why == nullptr ? StepStatus::ok : fault(why);
}

std::vector<Tunable> BankFilter::tunables() const { return {BiquadBank::enabled_tunable()}; }

double BankFilter::tunable_value(std::size_t index) const noexcept {
  return index == kEnabled ? bank_.enabled_value() : 0.0;
}

bool BankFilter::set_tunable(std::size_t index, double value, const char*& why) noexcept {
  if (index != kEnabled) {
    why = "no such parameter";
    return false;
  }
  return bank_.set_enabled_tunable(value, why);
}

}  // namespace lode::plugins::filter
