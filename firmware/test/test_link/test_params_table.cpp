// The rover's parameter table (messages_gen.h: each value in the least width its limits allow,
// little-endian, in flash) against the definition's numbers (vectors_gen.h, written by the
// generator from protocol/messages.toml), and the loader's widths and signs.
#include <doctest.h>

#include "messages_gen.h"
#include "vectors_gen.h"

using namespace rovernav;

TEST_CASE("every parameter's default and limits read back from the packed table as the definition has them") {
  int listed = 0;
  for (const ParamSpec& spec : kParamSpecs) {
    CAPTURE(spec.id);
    int32_t def = 0, lo = 0, hi = 0;
    REQUIRE(param_limits(spec.id, def, lo, hi));
    CHECK(def == spec.def);
    CHECK(lo == spec.lo);
    CHECK(hi == spec.hi);
    ++listed;
  }
  CHECK(listed == kParamMaxId);
  int32_t def = 0, lo = 0, hi = 0;
  CHECK_FALSE(param_limits(0, def, lo, hi));
  CHECK_FALSE(param_limits(static_cast<uint8_t>(kParamMaxId + 1), def, lo, hi));
}

TEST_CASE("each parameter's width holds its limits, and the widths tile the store") {
  int bytes = 0;
  for (const ParamSpec& spec : kParamSpecs) {
    CAPTURE(spec.id);
    const uint8_t at = kParamOffset[spec.id - 1];
    const uint8_t w = param_width(at);
    REQUIRE(static_cast<int>(at) + w <= kParamBytes);
    bytes += w;
    const int64_t span_lo = param_signed(at) ? -(int64_t{1} << (8 * w - 1)) : 0;
    const int64_t span_hi = param_signed(at) ? (int64_t{1} << (8 * w - 1)) - 1 : (int64_t{1} << (8 * w)) - 1;
    CHECK(spec.lo >= span_lo);
    CHECK(spec.hi <= span_hi);
    if (w < 4) {   // and no narrower width would do
      const int64_t narrower_hi = param_signed(at) ? (int64_t{1} << (4 * w - 1)) - 1 : (int64_t{1} << (4 * w)) - 1;
      const int64_t narrower_lo = param_signed(at) ? -(int64_t{1} << (4 * w - 1)) : 0;
      CHECK((w == 1 || spec.hi > narrower_hi || spec.lo < narrower_lo));
    }
  }
  CHECK(bytes == kParamBytes);
}

TEST_CASE("param_load sign-extends only signed values, in every width") {
  const uint8_t neg[4] = {0xFE, 0xFF, 0xFF, 0xFF};   // -2 as int32, int16 and int8
  CHECK(param_load(neg, 4, true, false) == -2);
  CHECK(param_load(neg, 2, true, false) == -2);
  CHECK(param_load(neg, 1, true, false) == -2);
  CHECK(param_load(neg, 2, false, false) == 0xFFFE);
  CHECK(param_load(neg, 1, false, false) == 0xFE);
  const uint8_t pos[4] = {0x34, 0x12, 0x7F, 0x00};
  CHECK(param_load(pos, 4, true, false) == 0x007F1234);
  CHECK(param_load(pos, 2, true, false) == 0x1234);
  CHECK(param_load(pos, 3, false, false) == 0x7F1234);
}
