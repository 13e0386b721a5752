// The lanes' kernel for AVX2, four lanes an instruction (this file alone is compiled with -mavx2,
// not -mfma: no fused multiply-add, so its numbers are the baseline kernel's and the
// one-manifold solve's).
#include "physics/steppers/soft_lanes.h"

#define SUBSTEP_LANES_KERNEL avx2Kernel
#define SUBSTEP_LANES_NAME "avx2"
#define SUBSTEP_LANES_WIDTH 4
#include "physics/steppers/soft_lanes_kernel.inc"
