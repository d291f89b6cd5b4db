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
 * libsimavr 1.6 (Debian) and the TWI master: two bugs, worked round in unocore_mpu.c (1, 2)
 *
 * libsimavr 1.6 and speed: two more things the harness sets right before the image runs
 *   3. Level-triggered INT0/INT1 polling. simavr's external-interrupt module, in its default
 *      "strict level triggering", starts a one-cycle timer that reads the port through an
 *      ioctl every cycle while INT0's or INT1's pin is low, whether or not the interrupt is
 *      enabled. INT1's pin is PD3, a motor input that is low whenever that motor is not
 *      reversing: the poll cost half of simavr's time. The image enables neither INT0 nor
 *      INT1, so the harness turns strict level triggering off for both (after every reset
 *      too, which turns it back on); a write to EIMSK that enables one of them turns it back
 *      on for that one.
 *   4. Phase-correct PWM modes. 1.6's timers lack them (Timer2's WGM 1, which the Arduino
 *      core's init() selects for pins 3 and 11, and Timer1's 1-3): the timer then runs with a
 *      TOP of 0 and its overflow timer fires every prescaled tick (every 64 cycles), which is
 *      harmless to the image (nothing uses Timer2's interrupts) but costs time and defeats the
 *      fast-forward below. The harness fills those modes in as the phase-and-frequency
 *      correct mode of the same resolution (TOP 0xFF, 0x1FF, 0x3FF), which simavr models
 *      with a period of TOP+1 ticks instead of the hardware's 2*TOP: the compare values, which
 *      are what the harness reads for the motors, are the same.
 *   5. Pull-ups across a reset. A port's pin IRQs are filtered (a raise that repeats the IRQ's
 *      last value notifies nobody), and a reset clears PINx but leaves the IRQs' last values. An
 *      input whose pull-up had made it high stays low after the reset: the firmware sets the
 *      pull-up again, the port raises 1, the IRQ already holds 1, and PINx is never set. The
 *      image would read the consent pin (board.h kPinConsent, D7) as held to GND after every
 *      reset. After each reset the harness sets every port pin IRQ's value to its PINx bit
 *      (without notifying), so the next raise of a different level reaches PINx.
 *
 * A pin held to GND: unocore_hold_pin_low sets the port's "external" state (simavr's model of
 * something driving an input), which wins over the pull-up while the DDR bit is clear and
 * outlives resets, as a jumper to GND does.
 *
 * Speed: idle fast-forward (exact): unocore_ff.c
 *
 * Time: unocore_run_to(cycle) runs the AVR until its cycle counter (continued across resets)
 * reaches the cycle the host asks for: t_s * 16e6.
 *
 * Profile: where a step's cycles go (unocore_profile_*, `rovernav sim --rover uno --profile`):
 *   unocore_prof.c.
 */
#define _GNU_SOURCE

#include <inttypes.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "avr_eeprom.h"
#include "avr_extint.h"
#include "avr_ioport.h"
#include "avr_timer.h"
#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_interrupts.h"
#include "sim_io.h"
#include "sim_irq.h"

#include "uart_line.h"
#include "unocore.h"
#include "unocore_ff.h"
#include "unocore_mpu.h"
#include "unocore_prof.h"

#define PAINT 0xA5              /* stack paint pattern */
#define SONAR_ECHO_DELAY_US 450u
#define SONAR_NO_ECHO_US 38000u

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

/* ------------------------------------------------------------------------------ sonar */

static avr_cycle_count_t echo_fall_timer(avr_t *avr, avr_cycle_count_t when, void *param)
{
	(void)avr;
	(void)when;
	unocore *u = param;
	avr_raise_irq(u->echo_irq, 0);
	u->echo_busy = 0;
	u->echoes_total++;
	u->dirty = 1;
	return 0;
}

static avr_cycle_count_t echo_rise_timer(avr_t *avr, avr_cycle_count_t when, void *param)
{
	(void)when;
	unocore *u = param;
	avr_raise_irq(u->echo_irq, 1);
	avr_cycle_timer_register_usec(avr, u->echo_us, echo_fall_timer, u);
	u->dirty = 1;
	return 0;
}

static void trig_hook(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	unocore *u = param;
	int level = (value & 1) != 0; /* simavr may flag output changes with AVR_IOPORT_OUTPUT */
	int rising = level && !u->trig_level;
	u->trig_level = level;
	u->dirty = 1;
	if (!rising)
		return;
	u->pings_total++;
	if (u->echo_busy) { /* the sensor ignores a trigger until its echo has ended */
		u->st.pings_ignored++;
		return;
	}
	uint32_t range_mm = u->sonar_fn ? u->sonar_fn(u->sonar_user) : 0;
	/* width_us = 2 * range / 0.343 mm/us; nothing in range: the HC-SR04's ~38 ms time-out */
	u->echo_us = range_mm ? (uint32_t)(((uint64_t)range_mm * 2000u + 171u) / 343u)
	                      : SONAR_NO_ECHO_US;
	if (u->echo_us > SONAR_NO_ECHO_US)
		u->echo_us = SONAR_NO_ECHO_US;
	u->echo_busy = 1;
	avr_cycle_timer_register_usec(u->avr, SONAR_ECHO_DELAY_US, echo_rise_timer, u);
}


/* ------------------------------------------------------------------------------ step probe */

static void pb0_hook(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	unocore *u = param;
	int level = (value & 1) != 0;
	if (level == u->pb0_level)
		return;
	u->pb0_level = level;
	u->dirty = 1;
	uint64_t now = now_cycle(u);
	if (u->prof.on) {
		if (level)
			prof_step_rise(&u->prof, now, u->st.resets);
		else
			prof_step_fall(&u->prof, now);
	}
	if (level) {
		if (u->nsteps == u->capsteps) {
			uint32_t cap = u->capsteps ? u->capsteps * 2 : 4096;
			unocore_step *s = realloc(u->steps, cap * sizeof *s);
			if (!s)
				return;
			u->steps = s;
			u->capsteps = cap;
		}
		unocore_step *s = &u->steps[u->nsteps++];
		memset(s, 0, sizeof *s);
		s->rise = now;
		s->boot = u->st.resets;
	} else if (u->nsteps > 0 && u->steps[u->nsteps - 1].fall == 0) {
		u->steps[u->nsteps - 1].fall = now;
	}
}

static void gpior0_write_hook(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
	unocore *u = param;
	avr->data[addr] = v;
	u->dirty = 1;
	u->last_desc = v;
	u->has_desc = 1;
	/* the descriptor belongs to the step that rose last (written before or after its fall),
	 * if that step was in this boot */
	if (u->nsteps > 0 && u->steps[u->nsteps - 1].boot == u->st.resets) {
		u->steps[u->nsteps - 1].desc = v;
		u->steps[u->nsteps - 1].has_desc = 1;
	}
	prof_step_desc(&u->prof, v, u->st.resets);
}

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

/* ------------------------------------------------------------------------------ simavr 1.6 */

/* Workaround 3 (see the top of the file). */
static void extint_polling_off(unocore *u)
{
	for (uint8_t i = 0; i < 2; i++)
		avr_extint_set_strict_lvl_trig(u->avr, i, (u->eimsk >> i) & 1);
}

static void eimsk_write_hook(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
	unocore *u = param;
	avr->data[addr] = v;
	u->dirty = 1;
	if ((v & 3) != (u->eimsk & 3)) {
		u->eimsk = v;
		extint_polling_off(u);
	}
	u->eimsk = v;
}

/* Workaround 4 (see the top of the file). */
static void timer_modes_fill_in(unocore *u)
{
	for (avr_io_t *io = u->avr->io_port; io; io = io->next) {
		if (!io->kind || strcmp(io->kind, "timer") != 0)
			continue;
		avr_timer_t *t = (avr_timer_t *)io;
		int wide = t->r_tcnth != 0;
		for (int mode = 1; mode <= (wide ? 3 : 1); mode++) {
			if (t->wgm_op[mode].kind != avr_timer_wgm_none)
				continue;
			t->wgm_op[mode].kind = avr_timer_wgm_fc_pwm;
			t->wgm_op[mode].size = (uint8_t)(7 + mode); /* 8, 9, 10 bits */
			t->wgm_op[mode].top = avr_timer_wgm_reg_constant;
			u->st.timer_modes_filled++;
		}
	}
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
	if (u->echo_busy) {
		u->echo_busy = 0;
		avr_raise_irq(u->echo_irq, 0);
	}
	mpu_after_reset(u);
	u->snap_valid = 0;
	u->dirty = 1;
	if (u->pb0_level) { /* a step cut short by the reset: end it here */
		u->pb0_level = 0;
		if (u->nsteps > 0 && u->steps[u->nsteps - 1].fall == 0)
			u->steps[u->nsteps - 1].fall = cycle_before;
		prof_step_cut(&u->prof, cycle_before);
	}
	u->st.resets++;
	u->eimsk = 0;
	extint_polling_off(u);
	stack_paint(u);
	uart_line_kick(&u->uart);
	/* 5: the pin IRQs' values as PINx now has them (see the head of this file) */
	for (int i = 0; i < 3; i++) {
		const uint8_t pin = avr->data[A_PINB + 3 * i];
		for (int b = 0; b < 8; b++) {
			avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ((char)('B' + i)), b);
			if (irq)
				irq->value = (pin >> b) & 1u;
		}
	}
}

/* ------------------------------------------------------------------------------ API */

UNOCORE_API uint32_t unocore_abi_version(void) { return UNOCORE_ABI_VERSION; }

/* sizeof the structs the host reads (cores/uno_harness.py checks its ctypes copies against these), in
 * this order: step, regs, stats, prof_info, prof_entry, prof_step. Returns how many there are. */
UNOCORE_API uint32_t unocore_struct_sizes(uint32_t* out, uint32_t n) {
  const uint32_t sizes[] = {sizeof(unocore_step), sizeof(unocore_regs), sizeof(unocore_stats),
                            sizeof(unocore_prof_info), sizeof(unocore_prof_entry), sizeof(unocore_prof_step)};
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
	avr_register_io_write(avr, A_EIMSK, eimsk_write_hook, u);
	extint_polling_off(u);
	timer_modes_fill_in(u);

	/* pins */
	u->echo_irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('C'), IOPORT_IRQ_PIN0);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('C'), IOPORT_IRQ_PIN1),
	                        trig_hook, u);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), IOPORT_IRQ_PIN0),
	                        pb0_hook, u);
	avr_register_io_write(avr, A_GPIOR0, gpior0_write_hook, u);

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
	int i = port - 'B';
	if (i < 0 || i > 2 || bit > 7)
		return -1;
	if (held)
		u->held_low[i] |= (uint8_t)(1u << bit);
	else
		u->held_low[i] &= (uint8_t)~(1u << bit);
	avr_ioport_external_t ext = { .name = (unsigned long)port, .mask = u->held_low[i], .value = 0 };
	if (avr_ioctl(u->avr, AVR_IOCTL_IOPORT_SET_EXTERNAL(port), &ext) != 0)
		return -1;
	/* Now, too, if the firmware already reads it as an input */
	const uint8_t ddr = u->avr->data[A_DDRB + 3 * i], prt = u->avr->data[A_PORTB + 3 * i];
	if (!(ddr & (1u << bit)))
		avr_raise_irq(avr_io_getirq(u->avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit),
		              held ? 0 : (prt >> bit) & 1u);
	return 0;
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

