// SPDX-License-Identifier: MIT
// HR_VECTOR_CLONES: a hot loop compiled twice on x86-64, for the baseline
// (SSE2) and for AVX2, the loader picking the one the CPU runs (GCC's
// target_clones): 8 floats or 4 doubles per instruction instead of 4 or 2.
// No FMA, so both give the same bits. Not under ThreadSanitizer: the clones'
// resolver runs before its run-time is set up.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__)
#define HR_VECTOR_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define HR_VECTOR_CLONES
#endif
