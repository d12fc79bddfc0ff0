#include "lode/sdk/component.hpp"

namespace lode {

// Key function: the vtable and typeinfo of Component live in the core library, so
// dynamic_cast works across dlopen'ed plugins.
Component::~Component() = default;

}  // namespace lode
