// A 16-bit boot counter in EEPROM: a boot id that changes on every reset.
#pragma once

#include <stdint.h>

namespace rovernav {
namespace hal {

// EEPROM layout (board::kEepromBootCounterAddr):
//
//   offset  type       meaning
//   0       uint16_t   boots so far, little-endian; a blank EEPROM (0xFFFF) wraps to 0
//
// One increment writes two bytes: about 7 ms with the CPU waiting on the EEPROM's own
// bounded write cycle. 100,000 erase/write cycles is 100,000 boots.
class BootCounter {
 public:
  // Reads, increments and stores the counter; returns the new value.
  static uint16_t increment();
  static uint16_t read();
};

}  // namespace hal
}  // namespace rovernav
