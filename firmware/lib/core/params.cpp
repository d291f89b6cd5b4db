#include "params.h"

namespace rovernav {
namespace core {

SetResult Params::set(uint8_t id, int32_t value) {
  int32_t def = 0, lo = 0, hi = 0;
  if (id == 0 || id > kParamMaxId || !param_limits(id, def, lo, hi)) return SetResult::UnknownParam;
  if (value < lo || value > hi) return SetResult::OutOfRange;
  raw_[id - 1] = value;
  return SetResult::Ok;
}

void Params::reset() {
  for (uint8_t id = 1; id <= kParamMaxId; ++id) {
    int32_t def = 0, lo = 0, hi = 0;
    raw_[id - 1] = param_limits(id, def, lo, hi) ? def : 0;
  }
}

}  // namespace core
}  // namespace rovernav
