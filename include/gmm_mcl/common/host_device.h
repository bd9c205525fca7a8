// Marks small inline math functions shared by the CPU and CUDA backends.
// Under nvcc they become __host__ __device__; the CPU build needs no CUDA headers.
#pragma once

#if defined(__CUDACC__)
#define GMM_MCL_HD __host__ __device__ __forceinline__
#else
#define GMM_MCL_HD inline
#endif
