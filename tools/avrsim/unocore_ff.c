/*
 * unocore_ff.c: the harness's idle fast-forward.
 *
 * Speed: idle fast-forward (exact)
 *   The firmware spends most of each 10 ms busy-waiting for millis() to move: loop() kicks the
 *   watchdog, reads millis(), returns; so does the calibration loop. simavr executes every one
 *   of those instructions, and its WDR costs an ioctl walk plus a cycle-timer re-registration.
 *   At each WDR the harness compares the complete CPU state (registers, I/O space, SRAM, SREG)
 *   with its state at the previous WDR. When they are identical, the same WDR was reached on
 *   the same stack, no cycle timer fired in between, no interrupt is pending, and no I/O
 *   register with a read or write side effect (TCNTx, UDR0, PINx, TWDR, ...) was touched, the
 *   iteration in between changed nothing and reads nothing that time changes: every following
 *   iteration is the same, cycle for cycle, until the next cycle timer (Timer0's overflow for
 *   millis(), a UART byte, a TWI step, an echo edge, the watchdog) fires. The harness then
 *   advances the cycle counter by a whole number of iterations, stopping short of that timer
 *   and of the time the host asked for. Nothing the firmware can observe changes: the timer
 *   fires at the same cycle, in the same instruction of the same iteration, as without the
 *   skip, and the WDR that follows re-arms the watchdog. unocore_set_fast_forward(0) turns
 *   it off (to check that claim, or to profile simavr itself).
 */
#include <string.h>

#include "sim_interrupts.h"
#include "sim_io.h"

#include "unocore_ff.h"

static uint8_t read_wrap(avr_t *avr, avr_io_addr_t addr, void *param)
{
	unocore *u = param;
	u->dirty = 1;
	io_hook_t *h = &u->orig_r[AVR_DATA_TO_IO(addr)];
	return ((avr_io_read_t)h->c)(avr, addr, h->param);
}

static void write_wrap(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
	unocore *u = param;
	u->dirty = 1;
	io_hook_t *h = &u->orig_w[AVR_DATA_TO_IO(addr)];
	((avr_io_write_t)h->c)(avr, addr, v, h->param);
}

/* Every I/O register with a read or write handler gets a wrapper that marks the iteration as
 * one that touched the outside: such an iteration is never taken as a template to repeat. */
void ff_wrap_io_handlers(unocore *u)
{
	avr_t *avr = u->avr;
	for (int i = 0; i < MAX_IO && i < MAX_IOs; i++) {
		if (avr->io[i].r.c && avr->io[i].r.c != read_wrap) {
			u->orig_r[i].c = (void *)avr->io[i].r.c;
			u->orig_r[i].param = avr->io[i].r.param;
			avr->io[i].r.c = read_wrap;
			avr->io[i].r.param = u;
		}
		if (avr->io[i].w.c && avr->io[i].w.c != write_wrap) {
			u->orig_w[i].c = (void *)avr->io[i].w.c;
			u->orig_w[i].param = avr->io[i].w.param;
			avr->io[i].w.c = write_wrap;
			avr->io[i].w.param = u;
		}
	}
}

/* Called with the PC on a WDR, before it executes. */
void ff_at_wdr_skip(unocore *u)
{
	avr_t *avr = u->avr;
	avr_cycle_timer_slot_p head = avr->cycle_timers.timer;
	int same = u->snap_valid && !u->dirty && u->snap_pc == avr->pc && avr->state == cpu_Running &&
	           u->snap_head == head && head && u->snap_head_when == head->when &&
	           u->snap_interrupt_state == avr->interrupt_state &&
	           memcmp(u->snap_sreg, avr->sreg, sizeof u->snap_sreg) == 0 &&
	           memcmp(u->snap, avr->data, u->snap_len) == 0 &&
	           !avr_has_pending_interrupts(avr);
	if (same) {
		uint64_t period = avr->cycle - u->snap_cycle;
		avr_cycle_count_t next = head->when;
		/* whole iterations that end strictly before the next timer and the run target */
		uint64_t limit_avr = u->target - u->base; /* target in avr->cycle units */
		if (next > limit_avr)
			next = limit_avr;
		if (period > 0 && next > avr->cycle + period) {
			uint64_t n = (next - avr->cycle - 1) / period;
			if (n > 0) {
				avr->cycle += n * period;
				u->st.skipped_cycles += n * period;
				u->st.skips++;
			}
		}
		u->snap_cycle = avr->cycle;
		u->dirty = 0;
		return;
	}
	memcpy(u->snap, avr->data, u->snap_len);
	memcpy(u->snap_sreg, avr->sreg, sizeof u->snap_sreg);
	u->snap_pc = avr->pc;
	u->snap_interrupt_state = avr->interrupt_state;
	u->snap_cycle = avr->cycle;
	u->snap_head = head;
	u->snap_head_when = head ? head->when : 0;
	u->snap_valid = 1;
	u->dirty = 0;
}
