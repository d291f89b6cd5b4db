#include "link_serial.h"

#include <avr/interrupt.h>
#include <avr/io.h>

#include "messages_gen.h"

namespace {

#ifdef SERIAL_RX_BUFFER_SIZE
constexpr uint8_t kRxBytes = SERIAL_RX_BUFFER_SIZE;
#else
constexpr uint8_t kRxBytes = rovernav::kUartBufferBytes;
#endif
#ifdef SERIAL_TX_BUFFER_SIZE
constexpr uint8_t kTxBytes = SERIAL_TX_BUFFER_SIZE;
#else
constexpr uint8_t kTxBytes = rovernav::kUartBufferBytes;
#endif
static_assert(kTxBytes >= rovernav::kUartBufferBytes && kRxBytes >= rovernav::kUartBufferBytes,
              "a whole frame must fit the serial buffers (uart_buffer_bytes, protocol/vehicle.toml)");

constexpr bool power_of_two_to_128(uint8_t n) { return n >= 2 && n <= 128 && (n & (n - 1)) == 0; }
static_assert(power_of_two_to_128(kRxBytes), "SERIAL_RX_BUFFER_SIZE: a power of two, 2..128");
static_assert(power_of_two_to_128(kTxBytes), "SERIAL_TX_BUFFER_SIZE: a power of two, 2..128");

// Each ring has free-running 8-bit indices: head - tail (mod 256) is the number of bytes
// held, 0..size, so every slot is usable; a slot is index & (size - 1). One side writes head,
// the other tail, and a single byte is read and written atomically, so neither needs an
// interrupt lock. The interrupt writes rx_head and tx_tail; the loop writes rx_tail and
// tx_head.
volatile uint8_t rx_ring[kRxBytes];
volatile uint8_t rx_head = 0;
volatile uint8_t rx_tail = 0;
volatile uint8_t tx_ring[kTxBytes];
volatile uint8_t tx_head = 0;
volatile uint8_t tx_tail = 0;

void disable_udre_interrupt() { UCSR0B = static_cast<uint8_t>(UCSR0B & ~_BV(UDRIE0)); }

}  // namespace

ISR(USART_RX_vect) {
  const uint8_t byte = UDR0;  // read even when dropped: it clears the interrupt
  const uint8_t head = rx_head;
  if (static_cast<uint8_t>(head - rx_tail) < kRxBytes) {
    rx_ring[head & (kRxBytes - 1)] = byte;
    rx_head = static_cast<uint8_t>(head + 1);
  }
}

ISR(USART_UDRE_vect) {
  const uint8_t tail = tx_tail;
  if (tail == tx_head) {  // nothing left: stop asking
    disable_udre_interrupt();
    return;
  }
  UDR0 = tx_ring[tail & (kTxBytes - 1)];
  tx_tail = static_cast<uint8_t>(tail + 1);
}

namespace rovernav {
namespace hal {

void LinkSerial::begin(uint32_t baud) {
  uint16_t ubrr = static_cast<uint16_t>((F_CPU / 4 / baud - 1) / 2);  // U2X0: F_CPU / 8 / baud
  bool double_speed = true;
  if ((F_CPU == 16000000UL && baud == 57600) || ubrr > 4095) {
    ubrr = static_cast<uint16_t>((F_CPU / 8 / baud - 1) / 2);  // F_CPU / 16 / baud
    double_speed = false;
  }
  UCSR0B = 0;
  UCSR0A = double_speed ? _BV(U2X0) : 0;
  UBRR0 = ubrr;
  UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
  UCSR0B = _BV(RXCIE0) | _BV(RXEN0) | _BV(TXEN0);
}

uint8_t LinkSerial::read_some(uint8_t* out, uint8_t max_len) {
  uint8_t tail = rx_tail;
  const uint8_t held = static_cast<uint8_t>(rx_head - tail);
  const uint8_t n = held < max_len ? held : max_len;
  for (uint8_t i = 0; i < n; ++i) {
    out[i] = rx_ring[tail & (kRxBytes - 1)];
    ++tail;
  }
  rx_tail = tail;
  return n;
}

uint8_t LinkSerial::write_some(const uint8_t* data, uint8_t len) {
  const uint8_t room = tx_free();
  const uint8_t n = len < room ? len : room;
  if (n == 0) return 0;
  uint8_t head = tx_head;
  for (uint8_t i = 0; i < n; ++i) {
    tx_ring[head & (kTxBytes - 1)] = data[i];
    ++head;
  }
  tx_head = head;
  // The interrupt may have just turned itself off on an empty ring; the bytes are in now.
  UCSR0B = static_cast<uint8_t>(UCSR0B | _BV(UDRIE0));
  return n;
}

uint8_t LinkSerial::tx_free() const {
  return static_cast<uint8_t>(kTxBytes - static_cast<uint8_t>(tx_head - tx_tail));
}

}  // namespace hal
}  // namespace rovernav
