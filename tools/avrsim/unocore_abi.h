/*
 * unocore_abi.h: what libunocore.so shares with its host, host/rovernav/cores/uno_harness.py,
 * which loads it with ctypes: the attribute that exports an entry point, the ABI version, the
 * sonar callback's type and the structs the host reads. The ctypes copies there must keep these
 * layouts (unocore_struct_sizes reports their sizes, and the host checks them when it loads).
 */
#ifndef ROVERNAV_UNOCORE_ABI_H
#define ROVERNAV_UNOCORE_ABI_H

#include <stdint.h>

#define UNOCORE_API __attribute__((visibility("default")))
#define UNOCORE_ABI_VERSION 3

typedef uint32_t (*unocore_sonar_fn)(void *user);

/* ------------------------------------------------------------------------------ structures
 * Shared with host/rovernav/cores/uno_harness.py (ctypes); keep the layouts in step. */

typedef struct unocore_step {
	uint64_t rise;           /* cycle PB0 went high */
	uint64_t fall;           /* cycle PB0 went low (0: not yet) */
	uint8_t desc;            /* GPIOR0 written during the step */
	uint8_t has_desc;
	uint8_t pad[2];
	uint32_t boot;           /* resets before this step: periods across a reset are gaps */
} unocore_step;

typedef struct unocore_regs {
	uint8_t tccr0a, ocr0a, ocr0b;
	uint8_t tccr2a, ocr2a, ocr2b;
	uint8_t portb, ddrb, portd, ddrd;
	uint8_t tccr1a, tccr1b;
	uint16_t icr1, ocr1a;
	uint8_t last_desc, has_desc;   /* the last step descriptor, if any */
	uint32_t pings;                /* TRIG rising edges so far */
	uint32_t echoes;               /* echo pulses completed so far */
	uint32_t steps;                /* PB0 rising edges so far */
} unocore_regs;

typedef struct unocore_stats {
	uint64_t cycle;                /* continued across resets */
	uint64_t skipped_cycles;       /* advanced by the idle fast-forward */
	uint64_t skips;
	uint32_t resets;               /* resets after the first boot (watchdog or unocore_reset) */
	int32_t cpu_state;             /* simavr's cpu_* of the last run */
	uint32_t crash_pc;
	uint32_t uart_bytes_in, uart_bytes_out, uart_xoffs, uart_rx_queued;
	uint32_t twi_addressed, twi_nacked, twi_bytes_written, twi_bytes_read;
	uint32_t twi_whoami_reads, twi_gyro_reads;
	uint32_t twi_status_fixed, twi_twint_cleared, twi_twsto_cleared;
	uint32_t pings, echoes, pings_ignored;
	uint16_t paint_start, ramend;
	uint16_t stack_lowest;         /* lowest painted address ever overwritten; ramend+1: none */
	uint16_t pad;
	uint32_t sim_warnings;
	uint32_t timer_modes_filled;
} unocore_stats;

/* The profile: the aggregates of one kind of step, and one of the longest steps. */
#define PROF_CTX 64              /* interrupt contexts: 0 the main line, 1.. the vectors */
#define PROF_KINDS 6             /* all, fix, sonar, replanning, radio_rx, none of the flags */

typedef struct unocore_prof_info {
	uint32_t nfuncs, nctx, nkeys, nkinds;   /* nkeys: nctx * nfuncs, then nedges */
	uint32_t nedges;                    /* nfuncs * nfuncs call edges of the main line, or 0 */
	uint32_t open_frames;               /* shadow frames still open when steps ended (0) */
	uint64_t steps[PROF_KINDS];
	uint64_t step_cycles[PROF_KINDS];   /* sum of fall - rise */
	uint64_t attributed[PROF_KINDS];    /* sum of the cycles counted inside those steps */
	uint64_t instructions;              /* instructions counted (in steps) */
	uint32_t worst_kept, worst_cap;
	uint32_t unfinished;                /* a step still open when the host asked */
	uint32_t depth_lost;                /* calls nested deeper than the shadow stack */
} unocore_prof_info;

typedef struct unocore_prof_entry {
	uint32_t key;                       /* context * nfuncs + function, or an edge (see info) */
	uint32_t cycles;                    /* self: at PCs inside the function */
	uint32_t calls;                     /* arrivals at one of its entry points from elsewhere */
	uint32_t incl;                      /* inclusive: from a CALL to it until its RET */
} unocore_prof_entry;

typedef struct unocore_prof_step {
	uint64_t rise, fall;
	uint8_t desc, has_desc;
	uint8_t pad[2];
	uint32_t n;                         /* entries */
} unocore_prof_step;

#endif /* ROVERNAV_UNOCORE_ABI_H */
