#include "boot_counter.h"

#include <avr/eeprom.h>

#include "board.h"

namespace rovernav {
namespace hal {

namespace {
uint8_t* counter_address() {
  return reinterpret_cast<uint8_t*>(board::kEepromBootCounterAddr);
}
}  // namespace

uint16_t BootCounter::read() {
  uint8_t b[2];
  eeprom_read_block(b, counter_address(), 2);
  return static_cast<uint16_t>(b[0] | (b[1] << 8));
}

uint16_t BootCounter::increment() {
  const uint16_t before = read();
  const uint16_t boots = static_cast<uint16_t>(before + 1U);
  // Byte by byte, each only if it changed (the high byte once in 256 boots), with the two
  // functions the link store uses already: eeprom_write_byte waits for the previous write.
  for (uint8_t i = 0; i < 2; ++i) {
    const uint8_t value = static_cast<uint8_t>(boots >> (8 * i));
    if (value != static_cast<uint8_t>(before >> (8 * i))) eeprom_write_byte(counter_address() + i, value);
  }
  return boots;
}

}  // namespace hal
}  // namespace rovernav
