/* C ABI of the rover core, for the simulator (Python ctypes) and other hosts.
 * Built as a shared library from the same sources as the Uno image (firmware/lib/core).
 * Lives outside lib/ on purpose: it allocates (one Rover per handle), which the core never does. */
#ifndef ROVERNAV_ROVER_ABI_H
#define ROVERNAV_ROVER_ABI_H
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define ROVER_ABI_VERSION 2
#define ROVER_TX_PER_STEP 64

typedef struct rover_inputs {
  uint32_t now_ms;
  uint8_t gyro_valid;
  int32_t gyro_rate_mdps;   /* clockwise positive */
  uint8_t sonar_valid;
  uint16_t sonar_range_mm;  /* 0 = no echo */
  uint8_t wheels_valid;
  int16_t left_ticks;
  int16_t right_ticks;
  const uint8_t* rx;
  uint8_t rx_len;
  uint8_t tx_room;
} rover_inputs;

typedef struct rover_outputs {
  int16_t left_pwm;
  int16_t right_pwm;
  int16_t servo_cdeg;
  uint8_t fire_sonar;
  uint8_t rx_used;          /* bytes of rx taken; give the rest again, first, next step */
  uint8_t tx_len;
  uint8_t tx[ROVER_TX_PER_STEP];
} rover_outputs;

/* What the simulator may look at without going through the link (for reports, never for control). */
typedef struct rover_probe {
  uint8_t state;
  uint8_t fault;
  uint16_t flags;
  uint8_t waypoint_index;
  uint8_t waypoint_count;
  float x_mm, y_mm, heading_rad;
  float position_sd_mm;
  float speed_scale;
  float dr_distance_mm;
} rover_probe;

uint32_t rover_abi_version(void);
/* The structs' layout as this library was compiled, for a host to check its own copy against:
 * writes at most `n` words (sizeof each struct, ROVER_TX_PER_STEP, then the offset of every field
 * of rover_inputs, rover_outputs and rover_probe, in declaration order); returns how many there are. */
uint32_t rover_abi_layout(uint32_t* out, uint32_t n);
uint32_t rover_schema_hash(void);
void* rover_new(uint32_t boot_id, uint16_t reset_cause);
/* A rover with a link key (16 bytes; NULL: none) and its stored signing counters. */
void* rover_new_keyed(uint32_t boot_id, uint16_t reset_cause, const uint8_t* key, uint64_t tx_counter,
                      uint64_t rx_counter);
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
