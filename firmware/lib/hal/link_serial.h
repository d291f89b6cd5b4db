// The serial link (3DR radio or USB) as bytes in and bytes out, never blocking.
#pragma once

#include <stdint.h>

namespace rovernav {
namespace hal {

// Hardware USART0 through the core's HardwareSerial, 8N1:
//
//   buffer  size      at 57,600 baud (5.76 bytes/ms)
//   RX      64 bytes  full after 11 ms: read every loop, and keep loops shorter than that
//   TX      64 bytes  63 usable; a longer write is split across loops by the caller
//
// Serial.write() blocks when its buffer is full; write_some() writes only what fits now.
class LinkSerial {
 public:
  void begin(uint32_t baud);

  // Copies up to max_len received bytes into out; returns how many (0 when none waited).
  uint8_t read_some(uint8_t* out, uint8_t max_len);

  // Queues as many of data's len bytes as the TX buffer takes now; returns how many.
  uint8_t write_some(const uint8_t* data, uint8_t len);

  // Free space in the TX buffer now.
  uint8_t tx_free() const;
};

}  // namespace hal
}  // namespace rovernav
