#include "link_serial.h"

#include <Arduino.h>

namespace rovernav {
namespace hal {

void LinkSerial::begin(uint32_t baud) { Serial.begin(baud); }

uint8_t LinkSerial::read_some(uint8_t* out, uint8_t max_len) {
  const int waiting = Serial.available();
  const uint8_t n = waiting < max_len ? static_cast<uint8_t>(waiting) : max_len;
  for (uint8_t i = 0; i < n; ++i) out[i] = static_cast<uint8_t>(Serial.read());
  return n;
}

uint8_t LinkSerial::write_some(const uint8_t* data, uint8_t len) {
  const uint8_t free_bytes = tx_free();
  const uint8_t n = len < free_bytes ? len : free_bytes;
  if (n == 0) return 0;
  return static_cast<uint8_t>(Serial.write(data, n));
}

uint8_t LinkSerial::tx_free() const {
  const int free_bytes = Serial.availableForWrite();
  if (free_bytes <= 0) return 0;
  return static_cast<uint8_t>(free_bytes > 255 ? 255 : free_bytes);
}

}  // namespace hal
}  // namespace rovernav
