/*
 * unocore: the rover's Uno image (build/uno/firmware.elf) in simavr, with the simulated world
 * wired to its pins, as a shared library (build/avrsim/libunocore.so) that the Python
 * simulator loads with ctypes (host/rovernav/cores/uno_harness.py, `rovernav sim --rover uno`).
 *
 * Why a library in the simulator's process and not a subprocess with a byte protocol
 *   The simulator steps the rover every 10 ms of simulated time, and an HC-SR04 ping needs the
 *   plant's range at the moment the firmware raises TRIG, which is in the middle of a step.
 *   In-process, that is one C-to-Python callback; across a pipe it would be a request and a
 *   reply inside the simulation loop (two context switches per ping, plus two per step). A
 *   ctypes call costs a microsecond; the AVR simulation of one step costs milliseconds, so the
 *   interface costs nothing measurable. ctypes releases the GIL while the AVR runs.
 *
 * What is wired to what (ATmega328P pins, see firmware/lib/hal/board.h)
 *   - Motors: the host reads TCCR0A/TCCR2A (are OC0A/OC0B/OC2A/OC2B connected?), OCR0A/B and
 *     OCR2A/B, and PORTB/PORTD for inputs held HIGH or LOW (analogWrite 0 and 255 disconnect
 *     the timer), at the end of every step (unocore_regs_read).
 *   - Servo: TCCR1A/TCCR1B/ICR1/OCR1A, read the same way; the host turns the pulse width into
 *     an angle with the board.h constants.
 *   - HC-SR04: a rising edge on TRIG (PC1) asks the host for the range (the plant's sonar
 *     model, through a callback); 450 us later ECHO (PC0) goes high for 2 * range / 0.343 us,
 *     or 38 ms when nothing echoes. The pin is driven through the port's pin IRQ, so the
 *     firmware sees it in PINC and through its pin-change interrupt alike.
 *   - MPU-6050: a TWI slave at 0x68 with a register file (auto-incrementing register pointer,
 *     WHO_AM_I 0x68, DEVICE_RESET, SLEEP, FS_SEL) whose GYRO_ZOUT is the host's yaw rate.
 *   - UART0: bytes from the host enter at the line rate (10 bits at 57,600 baud), and only
 *     while the UART has room (XON/XOFF); bytes the firmware sends are collected for the host
 *     (the line is uart_line.c's, shared with rovernav_avrsim.c).
 *   - Measurement hooks of the image, when present: PB0 (D8) high while a 10 ms step works,
 *     and GPIOR0 written with a step descriptor at its end. Every edge of PB0 is time-stamped
 *     in CPU cycles; each step record keeps its rise, its fall and its descriptor.
 *   - Stack: SRAM from the end of .bss/.noinit to RAMEND is painted with a pattern after
 *     loading (and after every reset); the lowest byte no longer holding it is the stack's
 *     high-water mark.
 *
 * Where the parts are (unocore.h lists the files)
 *   - unocore_mpu.c: the MPU-6050, and libsimavr 1.6 (Debian) and the TWI master: two bugs,
 *     worked round there (1, 2).
 *   - unocore_pins.c: the HC-SR04, the step probe, a pin held to GND, and libsimavr 1.6's
 *     external-interrupt polling, phase-correct PWM modes and pull-ups across a reset (3, 4, 5).
 *   - unocore_ff.c: Speed: idle fast-forward (exact).
 *   - unocore_prof.c: Profile: where a step's cycles go (unocore_profile_*,
 *     `rovernav sim --rover uno --profile`).
 *   - here: the entry points the host calls (unocore_abi.h has the structs they fill), the
 *     run loop, resets, the UART's queues and the stack's paint.
 *
 * Time: unocore_run_to(cycle) runs the AVR until its cycle counter (continued across resets)
 * reaches the cycle the host asks for: t_s * 16e6.
 */
#define _GNU_SOURCE

#include <inttypes.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "avr_eeprom.h"
#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_io.h"
#include "sim_irq.h"

#include "uart_line.h"
#include "unocore.h"
#include "unocore_ff.h"
#include "unocore_mpu.h"
#include "unocore_pins.h"
#include "unocore_prof.h"

#define PAINT 0xA5              /* stack paint pattern */

/* ------------------------------------------------------------------------------ logging */

static unsigned g_warnings;

static void sim_logger(avr_t *avr, const int level, const char *fmt, va_list ap)
{
	(void)avr;
	if (level == LOG_WARNING) {
		g_warnings++;
		return;
	}
	if (level > LOG_ERROR)
		return;
	fputs("simavr: ", stderr);
	vfprintf(stderr, fmt, ap);
}

static void no_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
	(void)avr;
	(void)how_long;
}

/* ------------------------------------------------------------------------------ rings */

static void ring_push(ring_t *r, uint8_t b)
{
	if (r->len == RING_BYTES) { /* full: drop the oldest (never happens at 57,600 baud) */
		r->head = (r->head + 1) % RING_BYTES;
		r->len--;
	}
	r->buf[(r->head + r->len) % RING_BYTES] = b;
	r->len++;
}

static uint8_t ring_pop(ring_t *r)
{
	uint8_t b = r->buf[r->head];
	r->head = (r->head + 1) % RING_BYTES;
	r->len--;
	return b;
}

/* ------------------------------------------------------------------------------ UART */

/* The line (uart_line.h) takes the bytes for the firmware from rx and puts what it sends in tx. */
static uint32_t uart_waiting(void *param) { return ((unocore *)param)->rx.len; }

static uint8_t uart_take(void *param) { return ring_pop(&((unocore *)param)->rx); }

static void uart_sent(void *param, uint8_t byte) { ring_push(&((unocore *)param)->tx, byte); }

/* ------------------------------------------------------------------------------ stack */

static void stack_paint(unocore *u)
{
	avr_t *avr = u->avr;
	if (u->paint_start == 0 || u->paint_start > avr->ramend)
		return;
	/* below the stack pointer only: at reset SP = RAMEND and nothing is on the stack yet */
	memset(avr->data + u->paint_start, PAINT, (size_t)avr->ramend + 1 - u->paint_start);
}

static void stack_measure(unocore *u)
{
	avr_t *avr = u->avr;
	if (u->paint_start == 0 || u->paint_start > avr->ramend)
		return;
	uint32_t a = u->paint_start;
	while (a <= avr->ramend && avr->data[a] == PAINT)
		a++;
	if (a < u->stack_lowest)
		u->stack_lowest = (uint16_t)a;
}

/* ------------------------------------------------------------------------------ resets */

/* After a reset of either kind: simavr cleared the cycle timers (the UART feed, the echo),
 * and possibly the cycle counter. The pins the harness drives go back to idle. */
static void after_reset(unocore *u, uint64_t cycle_before)
{
	avr_t *avr = u->avr;
	u->base = cycle_before - avr->cycle;
	u->last_avr_cycle = avr->cycle;
	uart_line_after_reset(&u->uart);
	sonar_after_reset(u);
	mpu_after_reset(u);
	u->snap_valid = 0;
	u->dirty = 1;
	probe_after_reset(u, cycle_before);
	u->st.resets++;
	extint_after_reset(u);
	stack_paint(u);
	uart_line_kick(&u->uart);
	pin_irqs_after_reset(u);   /* 5: see unocore_pins.c */
}

/* ------------------------------------------------------------------------------ API */

UNOCORE_API uint32_t unocore_abi_version(void) { return UNOCORE_ABI_VERSION; }

/* sizeof the structs the host reads (cores/uno_harness.py checks its ctypes copies against these), in
 * this order: step, regs, stats, prof_info, prof_entry, prof_step. Returns how many there are. */
UNOCORE_API uint32_t unocore_struct_sizes(uint32_t* out, uint32_t n) {
  const uint32_t sizes[] = {UNOCORE_ABI_STRUCT_SIZES};
  const uint32_t count = sizeof(sizes) / sizeof(sizes[0]);
  for (uint32_t i = 0; i < count && i < n; ++i) out[i] = sizes[i];
  return count;
}

UNOCORE_API void unocore_free(unocore *u)
{
	if (!u)
		return;
	if (u->avr)
		avr_terminate(u->avr);
	free(u->steps);
	free(u->snap);
	prof_free(&u->prof);
	free(u);
}

/*
 * Loads the ELF. paint_start: the first SRAM address above .data/.bss/.noinit (0: no stack
 * measurement). boot_counter: the EEPROM's boot counter (the firmware reports it + 1 as its
 * boot id). mcusr: the reset cause bits the first boot finds in MCUSR. mpu_addr: 7-bit address.
 * On failure returns NULL and writes why into err.
 */
UNOCORE_API unocore *unocore_new(const char *elf_path, uint16_t paint_start, uint16_t boot_counter,
                                 uint8_t mcusr, uint8_t mpu_addr, uint32_t baud,
                                 char *err, uint32_t errlen)
{
	avr_global_logger_set(sim_logger);
	unocore *u = calloc(1, sizeof *u);
	if (!u) {
		snprintf(err, errlen, "out of memory");
		return NULL;
	}
	if (elf_read_firmware(elf_path, &u->fw) != 0 || !u->fw.flash || !u->fw.flashsize) {
		snprintf(err, errlen, "cannot read an AVR program from %s", elf_path);
		free(u);
		return NULL;
	}
	if (u->fw.mmcu[0] == '\0')
		snprintf(u->fw.mmcu, sizeof u->fw.mmcu, "atmega328p");
	if (u->fw.frequency == 0)
		u->fw.frequency = 16000000u;
	u->avr = avr_make_mcu_by_name(u->fw.mmcu);
	if (!u->avr) {
		snprintf(err, errlen, "simavr does not know the MCU '%s'", u->fw.mmcu);
		free(u);
		return NULL;
	}
	avr_t *avr = u->avr;
	avr_init(avr);
	avr->log = LOG_WARNING;
	avr_load_firmware(avr, &u->fw);
	avr->sleep = no_sleep;

	/* UART0: no console echo, no usleep when the firmware polls; input paced at the line's rate */
	u->uart = (uart_line_t){.user = u, .waiting = uart_waiting, .take = uart_take, .sent = uart_sent};
	if (uart_line_attach(&u->uart, avr, '0', baud) != 0) {
		snprintf(err, errlen, "MCU %s has no UART0", u->fw.mmcu);
		unocore_free(u);
		return NULL;
	}

	/* TWI: the MPU-6050 (unocore_mpu.c) */
	if (mpu_attach(u, mpu_addr) != 0) {
		snprintf(err, errlen, "MCU %s has no TWI", u->fw.mmcu);
		unocore_free(u);
		return NULL;
	}

	/* pins, external interrupts, timers (unocore_pins.c) */
	pins_attach(u);

	/* EEPROM boot counter, little-endian at address 0 */
	uint8_t ee[2] = { (uint8_t)boot_counter, (uint8_t)(boot_counter >> 8) };
	avr_eeprom_desc_t d = { .ee = ee, .offset = 0, .size = 2 };
	avr_ioctl(avr, AVR_IOCTL_EEPROM_SET, &d);

	avr->data[A_MCUSR] = mcusr;

	u->paint_start = paint_start;
	u->stack_lowest = (uint16_t)(avr->ramend + 1);
	stack_paint(u);

	u->snap_len = (uint32_t)avr->ramend + 1;
	u->snap = malloc(u->snap_len);
	if (!u->snap) {
		snprintf(err, errlen, "out of memory");
		unocore_free(u);
		return NULL;
	}
	ff_wrap_io_handlers(u);
	u->ff_enabled = 1;
	u->last_avr_cycle = avr->cycle;
	u->base = 0 - (uint64_t)avr->cycle; /* the host's cycle 0 is now */
	return u;
}

UNOCORE_API void unocore_set_sonar(unocore *u, unocore_sonar_fn fn, void *user)
{
	u->sonar_fn = fn;
	u->sonar_user = user;
}

UNOCORE_API void unocore_set_fast_forward(unocore *u, int on) { u->ff_enabled = on != 0; }

/* chip_mdps: the MPU-6050's Z rate in its own frame (counter-clockwise positive), in
 * millidegrees per second; alive 0: the chip stops answering its address. */
UNOCORE_API void unocore_set_gyro(unocore *u, int alive, int32_t chip_mdps)
{
	u->gyro_alive = alive != 0;
	u->gyro_chip_mdps = chip_mdps;
}

/* An input pin held to GND (held != 0), as a jumper does, or let go (its pull-up, if the firmware
 * set one, makes it high again): the consent pin (board.h kPinConsent) a keyed image reads at
 * start-up. simavr 1.6 models an input's pull-up (PORT bit set, DDR bit clear) as a high pin; the
 * port's "external" state, set here, drives the pin instead while the DDR bit is clear, and
 * outlives resets (avr_reset leaves it), as a jumper does. Returns 0, or -1 for an unknown port. */
UNOCORE_API int unocore_hold_pin_low(unocore *u, char port, uint8_t bit, int held)
{
	return pins_hold_low(u, port, bit, held);
}

UNOCORE_API uint32_t unocore_rx(unocore *u, const uint8_t *data, uint32_t len)
{
	uint32_t n = 0;
	for (; n < len && u->rx.len < RING_BYTES; n++)
		ring_push(&u->rx, data[n]);
	uart_line_kick(&u->uart);
	return n;
}

UNOCORE_API uint32_t unocore_tx(unocore *u, uint8_t *out, uint32_t max)
{
	uint32_t n = 0;
	while (n < max && u->tx.len > 0)
		out[n++] = ring_pop(&u->tx);
	return n;
}

/* Runs until the cycle counter reaches `cycle`. Returns 0, or 1 when the AVR crashed or
 * stopped (it will not run again). */
UNOCORE_API int unocore_run_to(unocore *u, uint64_t cycle)
{
	avr_t *avr = u->avr;
	u->target = cycle;
	int state = avr->state;
	const int profiling = u->prof.on;
	while (u->base + avr->cycle < cycle) {
		if (u->ff_enabled && ff_at_wdr(avr))
			ff_at_wdr_skip(u);
		uint64_t before = u->base + avr->cycle;
		if (profiling && u->pb0_level && u->prof.active)
			state = prof_run(&u->prof, avr);   /* inside a step: counted (unocore_prof.c) */
		else
			state = avr_run(avr);
		if (state == cpu_Crashed || state == cpu_Done || state == cpu_Stopped) {
			u->st.crash_pc = avr->pc;
			break;
		}
		if (avr->pc == avr->reset_pc) {
			/* A watchdog reset: simavr restarted the core at its reset vector (nothing else
			 * jumps to 0), and may have zeroed its cycle counter. Nothing has run since. */
			stack_measure(u);
			after_reset(u, avr->cycle < u->last_avr_cycle ? before : u->base + avr->cycle);
		}
		u->last_avr_cycle = avr->cycle;
	}
	u->st.cpu_state = state;
	return state == cpu_Crashed || state == cpu_Done || state == cpu_Stopped;
}

/* A reset by the host (power cycle, reset button): MCUSR = mcusr; EEPROM and .noinit kept. */
UNOCORE_API void unocore_reset(unocore *u, uint8_t mcusr)
{
	avr_t *avr = u->avr;
	uint64_t before = now_cycle(u);
	stack_measure(u);
	avr_reset(avr);
	avr->data[A_MCUSR] = mcusr;
	after_reset(u, before);
}

UNOCORE_API void unocore_regs_read(unocore *u, unocore_regs *r)
{
	const uint8_t *d = u->avr->data;
	r->tccr0a = d[A_TCCR0A];
	r->ocr0a = d[A_OCR0A];
	r->ocr0b = d[A_OCR0B];
	r->tccr2a = d[A_TCCR2A];
	r->ocr2a = d[A_OCR2A];
	r->ocr2b = d[A_OCR2B];
	r->portb = d[A_PORTB];
	r->ddrb = d[A_DDRB];
	r->portd = d[A_PORTD];
	r->ddrd = d[A_DDRD];
	r->tccr1a = d[A_TCCR1A];
	r->tccr1b = d[A_TCCR1B];
	r->icr1 = (uint16_t)(d[A_ICR1L] | d[A_ICR1H] << 8);
	r->ocr1a = (uint16_t)(d[A_OCR1AL] | d[A_OCR1AH] << 8);
	r->last_desc = u->last_desc;
	r->has_desc = (uint8_t)u->has_desc;
	r->pings = u->pings_total;
	r->echoes = u->echoes_total;
	r->steps = u->nsteps;
}

/* Copies up to max step records not yet handed out. Without `final`, the last record stays
 * (its descriptor may still come); with it, the last one goes too once PB0 has fallen. */
UNOCORE_API uint32_t unocore_steps(unocore *u, unocore_step *out, uint32_t max, int final)
{
	uint32_t n = 0;
	uint32_t end = final ? u->nsteps : (u->nsteps > 0 ? u->nsteps - 1 : 0);
	while (n < max && u->drained < end && u->steps[u->drained].fall != 0)
		out[n++] = u->steps[u->drained++];
	if (u->drained > 0 && u->drained + 1 >= u->nsteps) { /* keep the array short */
		uint32_t keep = u->nsteps - u->drained;
		memmove(u->steps, u->steps + u->drained, keep * sizeof *u->steps);
		u->nsteps = keep;
		u->drained = 0;
	}
	return n;
}

UNOCORE_API void unocore_stats_read(unocore *u, unocore_stats *s)
{
	stack_measure(u);
	u->st.cycle = now_cycle(u);
	u->st.uart_bytes_in = (uint32_t)u->uart.bytes_in;
	u->st.uart_bytes_out = (uint32_t)u->uart.bytes_out;
	u->st.uart_xoffs = (uint32_t)u->uart.xoffs;
	u->st.uart_rx_queued = u->rx.len;
	u->st.pings = u->pings_total;
	u->st.echoes = u->echoes_total;
	u->st.paint_start = u->paint_start;
	u->st.ramend = u->avr->ramend;
	u->st.stack_lowest = u->stack_lowest;
	u->st.sim_warnings = g_warnings;
	*s = u->st;
}

/* Raw access for tests and diagnostics. */
UNOCORE_API uint8_t unocore_peek(unocore *u, uint16_t addr)
{
	return addr <= u->avr->ramend ? u->avr->data[addr] : 0;
}

UNOCORE_API uint32_t unocore_pc(unocore *u) { return u->avr->pc; }

/* Writes the EEPROM (the link key a `rovernav provision` would have stored, say) before the
 * image runs, or reads it back; 0 on success, -1 out of range. */
UNOCORE_API int unocore_eeprom(unocore *u, uint16_t offset, uint8_t *data, uint16_t size, int write)
{
	if ((uint32_t)offset + size > 1024u)
		return -1;
	avr_eeprom_desc_t d = { .ee = data, .offset = offset, .size = size };
	avr_ioctl(u->avr, write ? AVR_IOCTL_EEPROM_SET : AVR_IOCTL_EEPROM_GET, &d);
	if (!write) { /* EEPROM_GET points d.ee at the simulator's copy */
		for (uint16_t i = 0; i < size; i++)
			data[i] = d.ee[i];
	}
	return 0;
}

/*
 * Starts the profile (see unocore_prof.c), forgetting any earlier one. func_of_word: the
 * function index of each flash word (nwords of them; words beyond are function nfuncs - 1, the
 * host's "no symbol"); entry: 1 for each flash word where a function's symbol starts (an
 * arrival there from another function is a call);
 * worst_cap: how many of the longest steps keep their own table. Returns 0, or -1 (memory).
 */
UNOCORE_API int unocore_profile_start(unocore *u, const uint16_t *func_of_word, uint32_t nwords,
                                      const uint8_t *entry, uint32_t nfuncs, uint32_t worst_cap)
{
	return prof_start(&u->prof, func_of_word, nwords, entry, nfuncs, worst_cap);
}

/* The profile's counters, after folding in the last step if it has ended. */
UNOCORE_API void unocore_profile_info(unocore *u, unocore_prof_info *out)
{
	prof_info_read(&u->prof, out);
}

/* The aggregates of one kind of step: self cycles, calls and inclusive cycles by key (nkeys
 * each). Returns nkeys, or 0 for a kind that does not exist or no profile. */
UNOCORE_API uint32_t unocore_profile_read(unocore *u, uint32_t kind, uint64_t *cycles, uint64_t *calls,
                                          uint64_t *incl, uint32_t max)
{
	return prof_read(&u->prof, kind, cycles, calls, incl, max);
}

/* One of the longest steps kept (i < info.worst_kept, in no order): its header, and up to max
 * of its entries. Returns the number of entries copied. */
UNOCORE_API uint32_t unocore_profile_worst(unocore *u, uint32_t i, unocore_prof_step *hdr,
                                           unocore_prof_entry *out, uint32_t max)
{
	return prof_worst_read(&u->prof, i, hdr, out, max);
}

