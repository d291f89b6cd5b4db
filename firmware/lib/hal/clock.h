// The shell's millisecond clock: the Arduino core's millis(), out of line. Link-time
// optimisation pasted millis() (interrupts off round a four-byte read) at each of its four
// calls; one copy and four calls take less of the Uno's flash.
#pragma once

#include <stdint.h>

namespace rovernav {
namespace hal {

uint32_t clock_ms();

}  // namespace hal
}  // namespace rovernav
