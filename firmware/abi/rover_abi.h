/* C ABI of the rover core, for the simulator (Python ctypes) and other hosts.
 * Built as a shared library from the same sources as the Uno image (firmware/lib/core).
 * Lives outside lib/ on purpose: it allocates (one Rover per handle), which the core never does. */
#ifndef ROVERNAV_ROVER_ABI_H
#define ROVERNAV_ROVER_ABI_H
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define ROVER_ABI_VERSION 1
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
uint32_t rover_schema_hash(void);
void* rover_new(uint32_t boot_id, uint16_t reset_cause);
void rover_step(void* rover, const rover_inputs* in, rover_outputs* out);
void rover_probe_state(const void* rover, rover_probe* probe);
void rover_free(void* rover);

#ifdef __cplusplus
}
#endif
#endif
