#include "clock.h"

#include <Arduino.h>

namespace rovernav {
namespace hal {

__attribute__((noinline)) uint32_t clock_ms() { return millis(); }

}  // namespace hal
}  // namespace rovernav
