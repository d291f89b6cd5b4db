#include "boot_counter.h"

#include <avr/eeprom.h>

#include "board.h"

namespace rovernav {
namespace hal {

namespace {
uint16_t* counter_address() {
  return reinterpret_cast<uint16_t*>(board::kEepromBootCounterAddr);
}
}  // namespace

uint16_t BootCounter::read() { return eeprom_read_word(counter_address()); }

uint16_t BootCounter::increment() {
  const uint16_t boots = static_cast<uint16_t>(read() + 1U);
  eeprom_update_word(counter_address(), boots);
  return boots;
}

}  // namespace hal
}  // namespace rovernav
