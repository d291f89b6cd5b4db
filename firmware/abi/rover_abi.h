/* C ABI of the rover core, for the simulator (Python ctypes) and other hosts.
 * Built as a shared library from the same sources as the Uno image (firmware/lib/core).
 * Lives outside lib/ on purpose: it allocates (one Rover per handle), which the core never does. */
#ifndef ROVERNAV_ROVER_ABI_H
#define ROVERNAV_ROVER_ABI_H
#include <stdint.h>

/* ROVER_ABI_VERSION, ROVER_TX_PER_STEP and the structs rover_inputs, rover_outputs and rover_probe
 * are generated from firmware/abi/abi.toml (firmware/abi/generate.py), like their ctypes copies in
 * host/rovernav/cores/abi_gen.py. */
#include "rover_abi_gen.h"

#ifdef __cplusplus
extern "C" {
#endif

uint32_t rover_abi_version(void);
/* The structs' layout as this library was compiled, for a host to check its own copy against:
 * writes at most `n` words (ROVER_ABI_LAYOUT_WORDS: sizeof each struct, ROVER_TX_PER_STEP, then the
 * offset of every field of rover_inputs, rover_outputs and rover_probe, in declaration order);
 * returns how many there are. */
uint32_t rover_abi_layout(uint32_t* out, uint32_t n);
uint32_t rover_schema_hash(void);
void* rover_new(uint32_t boot_id, uint16_t reset_cause);
/* A rover with a link key (16 bytes; NULL: none), its stored signing counters and its fleet id
 * (0: a lone rover; 1..4: rover k of a fleet, protocol/messages.toml [fleet]); NULL for a fleet id
 * past 4. */
void* rover_new_keyed(uint32_t boot_id, uint16_t reset_cause, const uint8_t* key, uint64_t tx_counter,
                      uint64_t rx_counter, uint8_t fleet_id);
/* The fleet id the rover holds (begin's, or the last PROVISION's): what its shell stores with the key. */
int rover_fleet_id(const void* rover);
/* What the rover asks its shell to store: 1 and the counters when they are due (else 0). */
int rover_take_persist(void* rover, uint64_t* tx_counter, uint64_t* rx_counter);
/* A PROVISION taken: 1 store (key written to key_out, 16 bytes), 2 erase, 0 none. */
int rover_take_key_change(void* rover, uint8_t* key_out);
/* Frames refused for their signature: bad tag, replayed, not signed, unverified. */
void rover_auth_counters(const void* rover, uint16_t* out4);
void rover_step(void* rover, const rover_inputs* in, rover_outputs* out);
void rover_probe_state(const void* rover, rover_probe* probe);
void rover_free(void* rover);

#ifdef __cplusplus
}
#endif
#endif
