// The rover's frames out (TxQueue): however full it is filled, the frame at its head can still be
// framed, so the rover never goes silent.
#include <doctest.h>

#include "frame.h"
#include "frame_auth.h"
#include "messages_gen.h"
#include "tx_queue.h"

using namespace rovernav;

TEST_CASE("a queue filled to the last byte it takes still frames and sends, signed or not") {
  const uint8_t key[16] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16};
  for (int keyed = 0; keyed < 2; ++keyed) {
    CAPTURE(keyed);
    FrameAuth auth;
    if (keyed) auth.begin(key);
    core::TxQueue q;
    msg::Obstacle o{};
    o.range_mm = 321;
    // A sweep's echoes said thrice each while nothing leaves (the serial buffer full): the queue
    // fills until it refuses.
    int queued = 0;
    while (q.dropped() == 0 && queued < 100) {
      q.send(o);
      ++queued;
    }
    REQUIRE(q.dropped() == 1);
    CHECK(queued > 3);
    // The serial buffer empties: every frame queued goes out, whole and decodable.
    FrameDecoder dec;
    int decoded = 0;
    for (int step = 0; step < 400 && decoded < queued - 1; ++step) {
      uint8_t n = 0;
      const uint8_t* bytes = q.take(auth, 64, true, n);
      for (uint8_t i = 0; i < n; ++i) {
        if (dec.push(bytes[i])) {
          CHECK(dec.frame().msg_id == msg::Obstacle::kId);
          ++decoded;
        }
      }
    }
    CHECK(decoded == queued - 1);
    CHECK(q.size() == 0);
  }
}
