#include "element_source.hpp"

namespace lode::plugins::source {

Status ElementSource::activate() {
  output_.write_offset();
  return Status::ok();
}

}  // namespace lode::plugins::source
