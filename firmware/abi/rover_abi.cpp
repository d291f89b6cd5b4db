#include "rover_abi.h"

#include <stddef.h>

#include "rover.h"

using rovernav::core::Inputs;
using rovernav::core::Outputs;
using rovernav::core::Rover;

static_assert(ROVER_TX_PER_STEP == rovernav::core::kTxPerStep, "ABI and core agree on the TX chunk");

extern "C" {

uint32_t rover_abi_version(void) { return ROVER_ABI_VERSION; }

uint32_t rover_abi_layout(uint32_t* out, uint32_t n) {
  const uint32_t words[] = {ROVER_ABI_LAYOUT_WORDS};
  const uint32_t count = sizeof(words) / sizeof(words[0]);
  for (uint32_t i = 0; i < count && i < n; ++i) out[i] = words[i];
  return count;
}

uint32_t rover_schema_hash(void) { return rovernav::kSchemaHash; }

void* rover_new(uint32_t boot_id, uint16_t reset_cause) {
  Rover* r = new Rover();
  r->begin(boot_id, reset_cause);
  return r;
}

void* rover_new_keyed(uint32_t boot_id, uint16_t reset_cause, const uint8_t* key, uint64_t tx_counter,
                      uint64_t rx_counter, uint8_t fleet_id) {
  if (fleet_id > rovernav::kMaxRovers) return nullptr;
  rovernav::core::LinkSecrets s{};
  s.fleet_id = fleet_id;
  s.has_key = key != nullptr;
  for (uint8_t k = 0; key != nullptr && k < rovernav::kSipKeyBytes; ++k) s.key[k] = key[k];
  for (uint8_t k = 0; k < rovernav::kSignCounterBytes; ++k) {
    s.tx_counter.b[k] = static_cast<uint8_t>(tx_counter >> (8 * k));
    s.rx_counter.b[k] = static_cast<uint8_t>(rx_counter >> (8 * k));
  }
  Rover* r = new Rover();
  r->begin(boot_id, reset_cause, &s);
  return r;
}

int rover_take_persist(void* rover, uint64_t* tx_counter, uint64_t* rx_counter) {
  rovernav::Counter48 tx, rx;
  if (!static_cast<Rover*>(rover)->persist_due(tx, rx)) return 0;
  *tx_counter = *rx_counter = 0;
  for (uint8_t k = rovernav::kSignCounterBytes; k > 0; --k) {
    *tx_counter = (*tx_counter << 8) | tx.b[k - 1];
    *rx_counter = (*rx_counter << 8) | rx.b[k - 1];
  }
  return 1;
}

int rover_fleet_id(const void* rover) { return static_cast<const Rover*>(rover)->fleet_id(); }

int rover_take_key_change(void* rover, uint8_t* key_out) {
  Rover* r = static_cast<Rover*>(rover);
  const uint8_t change = r->take_key_change();
  if (change == Rover::kKeyStore) {
    for (uint8_t k = 0; k < rovernav::kSipKeyBytes; ++k) key_out[k] = r->link_key()[k];
  }
  return change;
}

void rover_auth_counters(const void* rover, uint16_t* out4) {
  const rovernav::AuthCounters& c = static_cast<const Rover*>(rover)->auth_counters();
  out4[0] = c.bad_tag;
  out4[1] = c.replayed;
  out4[2] = c.not_signed;
  out4[3] = c.unverified;
}

void rover_step(void* rover, const rover_inputs* in, rover_outputs* out) {
  Inputs i;
  i.now_ms = in->now_ms;
  i.gyro_valid = in->gyro_valid != 0;
  i.gyro_rate_mdps = in->gyro_rate_mdps;
  i.sonar_valid = in->sonar_valid != 0;
  i.sonar_range_mm = in->sonar_range_mm;
  i.wheels_valid = in->wheels_valid != 0;
  i.left_ticks = in->left_ticks;
  i.right_ticks = in->right_ticks;
  i.rx = in->rx;
  i.rx_len = in->rx_len;
  i.tx_room = in->tx_room;
  Outputs o;
  static_cast<Rover*>(rover)->step(i, o);
  out->left_pwm = o.left_pwm;
  out->right_pwm = o.right_pwm;
  out->servo_cdeg = o.servo_cdeg;
  out->fire_sonar = o.fire_sonar ? 1 : 0;
  out->rx_used = o.rx_used;
  out->tx_len = o.tx_len;
  for (uint8_t k = 0; k < o.tx_len; ++k) out->tx[k] = o.tx[k];
}

void rover_probe_state(const void* rover, rover_probe* probe) {
  const Rover* r = static_cast<const Rover*>(rover);
  probe->state = static_cast<uint8_t>(r->state());
  probe->fault = static_cast<uint8_t>(r->fault());
  probe->flags = r->flags();
  probe->waypoint_index = r->waypoint_index();
  probe->waypoint_count = r->waypoint_count();
  probe->x_mm = r->estimator().x_mm();
  probe->y_mm = r->estimator().y_mm();
  probe->heading_rad = r->estimator().heading_rad();
  probe->position_sd_mm = r->estimator().position_sd_mm();
  probe->speed_scale = r->speed_scale();
  probe->dr_distance_mm = r->dr_distance_mm();
}

void rover_free(void* rover) { delete static_cast<Rover*>(rover); }

}  // extern "C"
