/*
 * unocore_abi.h: what libunocore.so shares with its host, host/rovernav/cores/uno_harness.py,
 * which loads it with ctypes: the attribute that exports an entry point, the ABI version, the
 * sonar callback's type and the structs the host reads: those come from one definition,
 * firmware/abi/abi.toml, as C (unocore_abi_gen.h) and as ctypes (host/rovernav/cores/abi_gen.py);
 * unocore_struct_sizes reports their sizes, and the host checks them when it loads.
 */
#ifndef ROVERNAV_UNOCORE_ABI_H
#define ROVERNAV_UNOCORE_ABI_H

#include <stdint.h>

#define UNOCORE_API __attribute__((visibility("default")))

typedef uint32_t (*unocore_sonar_fn)(void *user);

/* The ABI version, PROF_CTX, PROF_KINDS and the structs the host reads (ctypes), generated with
 * their Python twins from firmware/abi/abi.toml by firmware/abi/generate.py. */
#include "unocore_abi_gen.h"

#endif /* ROVERNAV_UNOCORE_ABI_H */
