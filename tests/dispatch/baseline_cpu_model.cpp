// Linked into cpu_dispatch_probe_baseline only. The ifunc resolvers of GCC's function
// multiversioning (engine/src/platform/cpu_dispatch.hpp) read libgcc's CPU model, which
// __cpu_indicator_init fills from CPUID. These definitions replace libgcc's (the linker then
// takes nothing from its cpuinfo.o): a model with no feature at all, so every resolver picks the
// "default" (x86-64 baseline) version on any CPU. Layout of GCC 12's struct __processor_model;
// __cpu_features2 oversized (its length grows with GCC versions).
extern "C" {
struct {
  unsigned int vendor, type, subtype, features[1];
} __cpu_model = {};
unsigned int __cpu_features2[16] = {};
int __cpu_indicator_init() {
  return 0;
}
}
