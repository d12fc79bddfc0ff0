// A plugin whose own start-up code crashes: a static object's constructor that writes through
// a null pointer, as a plugin with a broken global initialiser would. It runs inside dlopen(),
// before the loader sees the plugin's descriptor.
namespace {

struct BrokenGlobal {
  BrokenGlobal() {
    volatile int* nowhere = null_;
    *nowhere = 1;
  }
  static inline int* volatile null_ = nullptr;  // volatile: the compiler cannot see the write fault
};

BrokenGlobal broken_global;

}  // namespace
