/*
 * unocore_prof.h: the cycle profile of the Uno image's steps (unocore_prof.c says how it counts).
 * Independent of the rest of the harness: it sees the AVR, the step edges and descriptors the
 * step probe hands it, and nothing else.
 */
#ifndef ROVERNAV_UNOCORE_PROF_H
#define ROVERNAV_UNOCORE_PROF_H

#include <stdint.h>

#include "sim_avr.h"

#include "unocore_abi.h"

typedef struct prof_worst {
	unocore_prof_step hdr;
	unocore_prof_entry *e;
} prof_worst;

#define PROF_DEPTH 64

typedef struct prof_frame {
	uint32_t key;
	uint32_t edge;                      /* the key of caller -> callee (UINT32_MAX: none) */
	uint8_t ctx;
	uint8_t tail;                       /* entered by a jump or by falling through, not a call */
	uint16_t nested;                    /* its function is already on the stack: no time of its own */
	uint32_t from;                      /* a tail frame: the function it was entered from */
	uint64_t clock;                     /* the context's clock at the call */
} prof_frame;

typedef struct prof {
	int on;
	const uint16_t *func_of_word;       /* copies, owned */
	uint32_t nwords;
	uint8_t *entry;                     /* by flash word: 1 where a function symbol starts */
	uint32_t nfuncs, nkeys, nkeys_fn;   /* nkeys_fn = PROF_CTX * nfuncs; edges after them */
	int edges;
	uint32_t *cur_cycles, *cur_calls, *cur_incl;   /* this step, by key */
	uint32_t *touched;                  /* the keys this step touched, each once */
	uint8_t *mark;                      /* by key: in touched */
	uint32_t ntouched;
	uint32_t last_key;
	uint64_t *agg_cycles, *agg_calls, *agg_incl;   /* [kind][key] */
	/* the shadow call stack (inclusive time); clocks count the cycles counted, the main
	 * line's alone and all of them (a frame in an interrupt handler uses the second) */
	prof_frame stack[PROF_DEPTH];
	uint32_t depth;
	uint32_t depth_lost;                /* calls deeper than PROF_DEPTH: not timed */
	uint64_t clock_main, clock_all;
	unocore_prof_info info;
	/* the step being counted */
	int active;
	uint64_t rise, fall, attributed;
	uint8_t desc, has_desc;
	uint32_t boot;
	/* the longest steps: a min-heap by duration */
	prof_worst *heap;
	uint32_t nheap, cap;
} prof_t;

/* Starts the profile, forgetting any earlier one (unocore_profile_start says what the arguments
 * are). Returns 0, or -1 (bad arguments, memory). */
int prof_start(prof_t *pr, const uint16_t *func_of_word, uint32_t nwords, const uint8_t *entry,
               uint32_t nfuncs, uint32_t worst_cap);
void prof_free(prof_t *pr);

/* The step probe's edges: PB0 rose at `now` (boot: the resets so far), PB0 fell, the step's
 * descriptor was written (it counts when the step being counted is of the same boot), and a
 * reset cut the step short at `now`. */
void prof_step_rise(prof_t *pr, uint64_t now, uint32_t boot);
void prof_step_fall(prof_t *pr, uint64_t now);
void prof_step_desc(prof_t *pr, uint8_t desc, uint32_t boot);
void prof_step_cut(prof_t *pr, uint64_t now);

/* Runs one instruction (avr_run) inside a step, counting its cycles; returns avr_run's state. */
int prof_run(prof_t *pr, avr_t *avr);

/* The figures the host reads (the unocore_profile_* entry points). */
void prof_info_read(prof_t *pr, unocore_prof_info *out);
uint32_t prof_read(prof_t *pr, uint32_t kind, uint64_t *cycles, uint64_t *calls, uint64_t *incl,
                   uint32_t max);
uint32_t prof_worst_read(const prof_t *pr, uint32_t i, unocore_prof_step *hdr,
                         unocore_prof_entry *out, uint32_t max);

#endif /* ROVERNAV_UNOCORE_PROF_H */
