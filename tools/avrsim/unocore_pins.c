/*
 * unocore_pins.c: what the harness wires to the Uno's pins, and simavr 1.6's port, external
 * interrupt and timer workarounds.
 *
 * What is wired to what here (ATmega328P pins, see firmware/lib/hal/board.h; unocore.c has
 * the whole board)
 *   - HC-SR04: a rising edge on TRIG (PC1) asks the host for the range (the plant's sonar
 *     model, through a callback); 450 us later ECHO (PC0) goes high for 2 * range / 0.343 us,
 *     or 38 ms when nothing echoes. The pin is driven through the port's pin IRQ, so the
 *     firmware sees it in PINC and through its pin-change interrupt alike.
 *   - Measurement hooks of the image, when present: PB0 (D8) high while a 10 ms step works,
 *     and GPIOR0 written with a step descriptor at its end. Every edge of PB0 is time-stamped
 *     in CPU cycles; each step record keeps its rise, its fall and its descriptor (and the
 *     profile, unocore_prof.c, hears of them).
 *   - The motors' and the servo's timers are only read (unocore_regs_read, in unocore.c), but
 *     simavr 1.6 needs Timer1's and Timer2's modes filled in (4).
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
 *      fast-forward (unocore_ff.c). The harness fills those modes in as the phase-and-frequency
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
 */
#include <stdlib.h>
#include <string.h>

#include "avr_extint.h"
#include "avr_ioport.h"
#include "avr_timer.h"
#include "sim_io.h"

#include "unocore_pins.h"

#define SONAR_ECHO_DELAY_US 450u
#define SONAR_NO_ECHO_US 38000u

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

/* ------------------------------------------------------------------------------ simavr 1.6 */

/* Workaround 3 (see the top of this file). */
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

/* Workaround 4 (see the top of this file). */
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

/* ------------------------------------------------------------------------------ wiring */

void pins_attach(unocore *u)
{
	avr_t *avr = u->avr;
	avr_register_io_write(avr, A_EIMSK, eimsk_write_hook, u);
	extint_polling_off(u);
	timer_modes_fill_in(u);
	u->echo_irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('C'), IOPORT_IRQ_PIN0);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('C'), IOPORT_IRQ_PIN1),
	                        trig_hook, u);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), IOPORT_IRQ_PIN0),
	                        pb0_hook, u);
	avr_register_io_write(avr, A_GPIOR0, gpior0_write_hook, u);
}

/* ------------------------------------------------------------------------------ resets */

void sonar_after_reset(unocore *u)
{
	if (u->echo_busy) {
		u->echo_busy = 0;
		avr_raise_irq(u->echo_irq, 0);
	}
}

void probe_after_reset(unocore *u, uint64_t cycle_before)
{
	if (u->pb0_level) { /* a step cut short by the reset: end it here */
		u->pb0_level = 0;
		if (u->nsteps > 0 && u->steps[u->nsteps - 1].fall == 0)
			u->steps[u->nsteps - 1].fall = cycle_before;
		prof_step_cut(&u->prof, cycle_before);
	}
}

void extint_after_reset(unocore *u)
{
	u->eimsk = 0;
	extint_polling_off(u);
}

/* Workaround 5 (see the top of this file): the pin IRQs' values as PINx now has them. */
void pin_irqs_after_reset(unocore *u)
{
	avr_t *avr = u->avr;
	for (int i = 0; i < 3; i++) {
		const uint8_t pin = avr->data[A_PINB + 3 * i];
		for (int b = 0; b < 8; b++) {
			avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ((char)('B' + i)), b);
			if (irq)
				irq->value = (pin >> b) & 1u;
		}
	}
}

/* ------------------------------------------------------------------------------ pins held low */

int pins_hold_low(unocore *u, char port, uint8_t bit, int held)
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
