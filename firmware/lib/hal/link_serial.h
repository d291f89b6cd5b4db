// The serial link (3DR radio or USB) as bytes in and bytes out, never blocking.
#pragma once

#include <stdint.h>

namespace rovernav {
namespace hal {

// USART0 (pins 0 and 1), 8N1, driven directly: the RX-complete interrupt fills one ring
// buffer and the data-register-empty interrupt drains the other. No Arduino HardwareSerial.
//
//   buffer  size (macro, as the Arduino core names it)   at 57,600 baud (5.76 bytes/ms)
//   RX      SERIAL_RX_BUFFER_SIZE, 64 unless set          128: full after 22 ms; read every loop
//   TX      SERIAL_TX_BUFFER_SIZE, 64 unless set          all of it usable; a longer write is
//                                                         split across loops by the caller
//
// platformio.ini sets the sizes; each must be a power of two from 2 to 128. A byte that
// arrives while RX is full is dropped, as HardwareSerial drops it.
//
//   register  value                     meaning
//   UCSR0A    U2X0 per begin()          double speed, except 57,600 baud at 16 MHz
//   UCSR0B    RXCIE0 | RXEN0 | TXEN0    receive with interrupt, transmit;
//             + UDRIE0                  only while TX bytes wait
//   UCSR0C    UCSZ01 | UCSZ00           8 data bits, no parity, 1 stop bit
//   UBRR0     begin()                   57,600 baud: 16 at normal speed (58,824 baud, +2.1 %)
class LinkSerial {
 public:
  // The divisor is the Arduino core's: double speed (U2X0) rounds to the nearer rate, but at
  // 57,600 baud on a 16 MHz board it uses normal speed, which the Uno's USB-serial chip
  // expects.
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
