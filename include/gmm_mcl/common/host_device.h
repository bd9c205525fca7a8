// Marks small inline math functions shared by the CPU and CUDA backends.
// Under nvcc they become __host__ __device__; the CPU build needs no CUDA headers.
#pragma once

#if defined(__CUDACC__)
#define GMM_MCL_HD __host__ __device__ __forceinline__
#else
#define GMM_MCL_HD inline
#endif

// Defined where a fused multiply-add is a single instruction (CUDA devices, x86 with -mfma,
// ARMv8). Code whose float results must not depend on the compiler's contraction choices (the
// membership tests: the vectorised and brute-force paths must decide alike at every -O level)
// writes its FMAs out with fmaf there and uses none elsewhere.
#if defined(__CUDA_ARCH__) || defined(__FMA__) || defined(__ARM_FEATURE_FMA)
#define GMM_MCL_EXPLICIT_FMA 1
#endif
