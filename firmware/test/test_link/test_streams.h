// Deterministic pseudo-random numbers for tests (xorshift32): the same seed, the same run.
#pragma once
#include <stdint.h>

namespace rovernav {
namespace test {

class XorShift {
 public:
  explicit XorShift(uint32_t seed) : state_(seed ? seed : 1u) {}
  uint32_t next() {
    state_ ^= state_ << 13;
    state_ ^= state_ >> 17;
    state_ ^= state_ << 5;
    return state_;
  }

 private:
  uint32_t state_;
};

}  // namespace test
}  // namespace rovernav
