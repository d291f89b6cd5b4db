/*
 * unocore.h: the harness's state (struct unocore), which its modules share, and the ATmega328P
 * registers they touch. unocore.c has the overview; the modules:
 *   unocore.c        the entry points the host calls (lifecycle, run loop, resets, UART, reads)
 *   unocore_mpu.c    the MPU-6050 on the TWI bus, with libsimavr 1.6's TWI workarounds (1, 2)
 *   unocore_pins.c   the HC-SR04, the step probe (PB0, GPIOR0), pins held low, and the pin,
 *                    external-interrupt and timer workarounds (3, 4, 5)
 *   unocore_ff.c     the idle fast-forward
 *   unocore_prof.c   the cycle profile (its own state, prof_t; it does not see this struct)
 *   uart_line.c      the serial line into UART0, shared with rovernav_avrsim.c
 * unocore_abi.h has what the host's ctypes code shares.
 */
#ifndef ROVERNAV_UNOCORE_H
#define ROVERNAV_UNOCORE_H

#include <stdint.h>

#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_irq.h"

#include "uart_line.h"
#include "unocore_abi.h"
#include "unocore_prof.h"

/* ATmega328P data-space addresses (datasheet register summary) */
enum {
	A_PINB = 0x23, A_DDRB = 0x24, A_PORTB = 0x25,
	A_PINC = 0x26, A_DDRC = 0x27, A_PORTC = 0x28,
	A_PIND = 0x29, A_DDRD = 0x2A, A_PORTD = 0x2B,
	A_GPIOR0 = 0x3E,
	A_EIMSK = 0x3D,
	A_TCCR0A = 0x44, A_TCCR0B = 0x45, A_OCR0A = 0x47, A_OCR0B = 0x48,
	A_MCUSR = 0x54,
	A_TCCR1A = 0x80, A_TCCR1B = 0x81, A_ICR1L = 0x86, A_ICR1H = 0x87,
	A_OCR1AL = 0x88, A_OCR1AH = 0x89,
	A_TCCR2A = 0xB0, A_TCCR2B = 0xB1, A_OCR2A = 0xB3, A_OCR2B = 0xB4,
	A_TWSR = 0xB9, A_TWDR = 0xBB, A_TWCR = 0xBC,
};

#define RING_BYTES 4096u
#define MAX_IO 256              /* I/O addresses 0x20..0xFF: io index 0..0xDF */
#define MPU_REGS 128

typedef struct ring {
	uint8_t buf[RING_BYTES];
	uint32_t head, len;
} ring_t;

typedef struct io_hook {
	void *param;
	void *c;
} io_hook_t;

typedef struct unocore {
	avr_t *avr;
	elf_firmware_t fw;
	char error[256];

	uint64_t base;                 /* cycles run before the last reset */
	uint64_t last_avr_cycle;

	/* UART0 (uart_line.c): bytes for the firmware wait in rx, what it sends waits in tx */
	uart_line_t uart;
	ring_t rx, tx;

	/* TWI: the MPU-6050 (unocore_mpu.c) */
	avr_irq_t *twi_in;
	uint8_t mpu_addr;
	int gyro_alive;
	int32_t gyro_chip_mdps;        /* the chip's frame: counter-clockwise positive */
	uint8_t regs[MPU_REGS];
	uint8_t reg_ptr;
	int selected;                  /* addressed since the last START/STOP */
	int first_write;               /* the next byte written is the register pointer */
	int addr_w_status_pending;     /* the next status is the answer to an SLA+W */
	uint8_t latch[14];             /* sensor registers 0x3B..0x48, latched at SLA+R */

	/* sonar (unocore_pins.c) */
	unocore_sonar_fn sonar_fn;
	void *sonar_user;
	avr_irq_t *echo_irq;
	int trig_level;
	int echo_busy;                 /* from TRIG until the echo has fallen */
	uint32_t echo_us;

	/* probe and descriptor (unocore_pins.c) */
	int pb0_level;
	unocore_step *steps;
	uint32_t nsteps, capsteps;
	uint32_t drained;              /* records [0, drained) went to the host */
	uint8_t last_desc;
	int has_desc;

	uint8_t eimsk;                 /* the last EIMSK written (unocore_pins.c, workaround 3) */

	/* stack (unocore.c) */
	uint16_t paint_start;
	uint16_t stack_lowest;

	/* fast-forward (unocore_ff.c); every hook of the harness sets dirty */
	int ff_enabled;
	int dirty;
	uint8_t *snap;
	uint32_t snap_len;
	uint8_t snap_sreg[8];
	int snap_valid;
	uint32_t snap_pc;
	int8_t snap_interrupt_state;
	uint64_t snap_cycle;
	avr_cycle_timer_slot_p snap_head;
	avr_cycle_count_t snap_head_when;
	uint64_t target;               /* never skip past the cycle being run to */
	io_hook_t orig_r[MAX_IO], orig_w[MAX_IO];

	unocore_stats st;
	uint32_t pings_total, echoes_total;

	prof_t prof;                   /* unocore_prof.c */
	uint8_t held_low[3];           /* pins held to GND by the host, ports B, C, D (unocore_hold_pin_low) */
} unocore;

static inline uint64_t now_cycle(const unocore *u) { return u->base + u->avr->cycle; }

#endif /* ROVERNAV_UNOCORE_H */
