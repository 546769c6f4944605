/* vector_clones.h - an AVX2 clone for the hot loops. */
#ifndef STF_VECTOR_CLONES_H
#define STF_VECTOR_CLONES_H

/* The hot neighbour loops get an AVX2 clone on x86-64 with GCC, chosen at load time. Same
 * results as the plain version: in ISO C mode GCC contracts no multiply-add into an FMA, and
 * the loops add up in the same order. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define STF_VECTOR_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define STF_VECTOR_CLONES
#endif

#endif
