// avx2_clones.hpp - RBX1_AVX2_CLONES: compile a pixel loop twice, for AVX2 and for any x86-64, and let the
// loader pick the clone for the CPU it runs on (GCC's target_clones, an ifunc).
#pragma once

// Not under ThreadSanitizer: an ifunc's resolver runs while the loader relocates the program, before the TSan
// runtime is set up, and the resolver's instrumentation then crashes the program before main.
#if defined(__x86_64__) && !defined(__SANITIZE_THREAD__)
#define RBX1_AVX2_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define RBX1_AVX2_CLONES
#endif
