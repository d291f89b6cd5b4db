/*
 * unocore_ff.h: the idle fast-forward (unocore_ff.c).
 */
#ifndef ROVERNAV_UNOCORE_FF_H
#define ROVERNAV_UNOCORE_FF_H

#include "unocore.h"

/* Once every I/O handler is registered: wraps them so that an iteration touching one is never
 * repeated by the fast-forward. */
void ff_wrap_io_handlers(unocore *u);

/* The PC is on a WDR (checked before each instruction, while the fast-forward is on). */
static inline int ff_at_wdr(const avr_t *avr)
{
	uint32_t pc = avr->pc;
	return pc + 1 <= avr->flashend && avr->flash[pc] == 0xA8 && avr->flash[pc + 1] == 0x95;
}

/* Called with the PC on a WDR, before it executes: skips whole idle iterations, or takes this
 * one as the template for the next. */
void ff_at_wdr_skip(unocore *u);

#endif /* ROVERNAV_UNOCORE_FF_H */
