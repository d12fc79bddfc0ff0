// A block that breaks the real-time contract by allocating in step(), through one chosen
// allocator path, from a given cycle on. The no-allocation tests must catch every path: a
// guard that misses one would let a plugin that uses it pass.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <malloc.h>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "lode/sdk/block.hpp"
#include "lode/sdk/plugin.hpp"

namespace {

/// Keeps the compiler from removing an allocation whose result is unused.
void escape(const void* p) { asm volatile("" : : "g"(p) : "memory"); }

struct alignas(64) OverAligned {
  double values[8];
};

// Every path the allocation counter claims to see, by name.
constexpr const char* kPaths[] = {"new",          "new_array",      "aligned_new", "nothrow_new", "malloc",
                                  "calloc",       "realloc",        "reallocarray", "posix_memalign",
                                  "aligned_alloc", "memalign",      "valloc",      "pvalloc",     "strdup",
                                  "std_string",   "std_vector",     "eigen_dynamic", "shared_ptr"};

[[gnu::noinline]] void allocate_once(const std::string& path) {
  if (path == "new") {
    auto* p = new double(1.0);
    escape(p);
    delete p;
  } else if (path == "new_array") {
    auto* p = new double[16];
    escape(p);
    delete[] p;
  } else if (path == "aligned_new") {
    auto* p = new OverAligned;
    escape(p);
    delete p;
  } else if (path == "nothrow_new") {
    auto* p = new (std::nothrow) double(1.0);
    escape(p);
    delete p;
  } else if (path == "malloc") {
    void* p = std::malloc(32);
    escape(p);
    std::free(p);
  } else if (path == "calloc") {
    void* p = std::calloc(4, 8);
    escape(p);
    std::free(p);
  } else if (path == "realloc") {
    void* p = std::realloc(nullptr, 32);
    escape(p);
    std::free(p);
  } else if (path == "reallocarray") {
    void* p = reallocarray(nullptr, 4, 8);
    escape(p);
    std::free(p);
  } else if (path == "posix_memalign") {
    void* p = nullptr;
    if (posix_memalign(&p, 64, 64) == 0) escape(p);
    std::free(p);
  } else if (path == "aligned_alloc") {
    void* p = std::aligned_alloc(64, 64);
    escape(p);
    std::free(p);
  } else if (path == "memalign") {
    void* p = memalign(64, 64);
    escape(p);
    std::free(p);
  } else if (path == "valloc") {
    void* p = valloc(64);
    escape(p);
    std::free(p);
  } else if (path == "pvalloc") {
    void* p = pvalloc(64);
    escape(p);
    std::free(p);
  } else if (path == "strdup") {
    char* p = strdup("a string copied on the heap");
    escape(p);
    std::free(p);
  } else if (path == "std_string") {
    std::string s(64, 'x');
    escape(s.data());
  } else if (path == "std_vector") {
    std::vector<double> v(16, 1.0);
    escape(v.data());
  } else if (path == "eigen_dynamic") {
    Eigen::MatrixXd m = Eigen::MatrixXd::Identity(6, 6);
    escape(m.data());
  } else if (path == "shared_ptr") {
    auto p = std::make_shared<double>(1.0);
    escape(p.get());
  }
}

class AllocatesInStep final : public lode::Block {
 public:
  lode::Status configure(lode::ConfigureContext& ctx) override {
    std::vector<std::string> paths(std::begin(kPaths), std::end(kPaths));
    path_ = ctx.params().choice("path", paths, "malloc");
    from_cycle_ = static_cast<std::uint64_t>(ctx.params().integer("from_cycle", 0));
    ctx.declare_output(out_, "out", {{"cycles", "1"}});
    return {};
  }
  lode::StepStatus step(const lode::Tick& tick) noexcept override {
    // The exception-free paths above only throw std::bad_alloc, which cannot happen here;
    // catching keeps step() honest to its noexcept.
    try {
      if (tick.cycle >= from_cycle_) allocate_once(path_);
    } catch (...) {
      return fault("allocation failed");
    }
    out_[0] = static_cast<double>(tick.cycle);
    return lode::StepStatus::ok;
  }

 private:
  lode::OutputPort out_;
  std::string path_;
  std::uint64_t from_cycle_ = 0;
};

constexpr lode::ParamDoc kParams[] = {
    {"path", "text", "malloc",
     "new, new_array, aligned_new, nothrow_new, malloc, calloc, realloc, reallocarray, posix_memalign, "
     "aligned_alloc, memalign, valloc, pvalloc, strdup, std_string, std_vector, eigen_dynamic or shared_ptr"},
    {"from_cycle", "integer", "0", "the first cycle whose step() allocates"},
};
constexpr lode::PortSpec kPorts[] = {{"out", lode::PortDirection::out, "the cycle number"}};

}  // namespace

LODE_PLUGIN(AllocatesInStep, "test.allocates_in_step", lode::PluginKind::block, "0.0.1",
            "Test plugin: step() allocates through a chosen allocator path", kParams, kPorts)
