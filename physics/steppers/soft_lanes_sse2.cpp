// The lanes' kernel for the baseline x86-64 (four lanes an operation, two an instruction), and the
// choice between it, the AVX2 one and the AVX-512 one at run time.
#include "physics/steppers/soft_lanes.h"

#include <atomic>

#define SUBSTEP_LANES_KERNEL sse2Kernel
#define SUBSTEP_LANES_NAME "sse2"
#define SUBSTEP_LANES_WIDTH 4
#include "physics/steppers/soft_lanes_kernel.inc"

namespace substep::lanes {

// __builtin_cpu_supports takes only a literal, so one function a feature, under one guard.
#if defined(__x86_64__) || defined(__i386__)
bool avx2Supported() { return __builtin_cpu_supports("avx2"); }
bool avx512Supported() { return __builtin_cpu_supports("avx512f"); }
#else
bool avx2Supported() { return false; }
bool avx512Supported() { return false; }
#endif

namespace {
std::atomic<const Kernel*> chosen{nullptr};
}

const Kernel& kernel() {
  static const Kernel& widest = avx512Supported() ? avx512Kernel() : avx2Supported() ? avx2Kernel() : sse2Kernel();
  const Kernel* k = chosen.load(std::memory_order_relaxed);
  return k ? *k : widest;
}

void useKernel(const Kernel* k) { chosen.store(k, std::memory_order_relaxed); }

}  // namespace substep::lanes
