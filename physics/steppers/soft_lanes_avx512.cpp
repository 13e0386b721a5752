// The lanes' kernel for AVX-512, eight lanes an instruction (this file alone is compiled with
// -mavx512f and -ffp-contract=off: AVX-512 has fused multiply-adds, which would round once where
// the baseline kernel and the one-manifold solve round twice).
#include "physics/steppers/soft_lanes.h"

#define SUBSTEP_LANES_KERNEL avx512Kernel
#define SUBSTEP_LANES_NAME "avx512"
#define SUBSTEP_LANES_WIDTH 8
#include "physics/steppers/soft_lanes_kernel.inc"
