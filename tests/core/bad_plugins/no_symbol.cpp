// A shared object that is not a lodestone plugin: it exports no descriptor.
extern "C" int lode_test_something_else() { return 42; }
