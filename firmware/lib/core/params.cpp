#include "params.h"

#include <string.h>

namespace rovernav {
namespace core {

int32_t Params::raw(Param p) const {
  // Read straight from RAM by the region the value lies in (the widest first): a few comparisons
  // and a load, where the generic loader's byte loop cost the Uno some 8 us a read, 25 reads a step.
  const uint8_t at = flash_read_u8(&kParamOffset[static_cast<uint8_t>(p) - 1]);
  const uint8_t* v = store_ + at;
  if (at < kParamAtU16) {
    int32_t x;
    memcpy(&x, v, sizeof x);
    return x;
  }
  if (at < kParamAtU8) {
    uint16_t x;
    memcpy(&x, v, sizeof x);
    return at < kParamAtI16 ? static_cast<int32_t>(x) : static_cast<int32_t>(static_cast<int16_t>(x));
  }
  return at < kParamAtI8 ? static_cast<int32_t>(*v) : static_cast<int32_t>(static_cast<int8_t>(*v));
}

SetResult Params::set(uint8_t id, int32_t value) {
  int32_t def = 0, lo = 0, hi = 0;
  if (!param_limits(id, def, lo, hi)) return SetResult::UnknownParam;
  if (value < lo || value > hi) return SetResult::OutOfRange;
  store(id, value);
  return SetResult::Ok;
}

void Params::reset() {
  for (uint8_t id = 1; id <= kParamMaxId; ++id) {
    int32_t def = 0, lo = 0, hi = 0;
    if (param_limits(id, def, lo, hi)) store(id, def);
  }
}

// Writes value (within the parameter's limits, so within its width) little-endian into its place.
ROVERNAV_NOINLINE void Params::store(uint8_t id, int32_t value) {
  const uint8_t at = flash_read_u8(&kParamOffset[id - 1]);
  uint32_t u = static_cast<uint32_t>(value);
  for (uint8_t i = 0; i < param_width(at); ++i, u >>= 8) store_[at + i] = static_cast<uint8_t>(u);
}

}  // namespace core
}  // namespace rovernav
