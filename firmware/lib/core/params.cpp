#include "params.h"

namespace rovernav {
namespace core {

int32_t Params::raw(Param p) const {
  const uint8_t at = flash_read_u8(&kParamOffset[static_cast<uint8_t>(p) - 1]);
  return param_load(store_ + at, param_width(at), param_signed(at), false);
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
