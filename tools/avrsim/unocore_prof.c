/*
 * unocore_prof.c: the cycle profile of the Uno image's steps, for unocore.c's
 * unocore_profile_* entry points.
 *
 * Profile: where a step's cycles go (unocore_profile_*, `rovernav sim --rover uno --profile`)
 *   Off unless the host calls unocore_profile_start with a map from flash word to function
 *   (from the ELF's symbol table; uno.py builds it). Then, while PB0 is high, every executed
 *   instruction's cycles go to the function whose symbol holds the PC it executed at: counted
 *   per instruction, not sampled. The run loop already calls simavr once per instruction (the
 *   fast-forward needs that), so the count is exact: the cycle counter's difference across one
 *   avr_run. Each instruction also carries its interrupt context: the vector of the innermost
 *   interrupt simavr is running (its running stack, pushed at the entry, popped by RETI), 0 in
 *   the main line; the key is context * functions + function, so a handler and what it calls
 *   are counted apart from the same functions called from the main line. An interrupt's entry
 *   costs the interrupted instruction's avr_run too: that call's cycles (the instruction's and
 *   the entry's) go to the handler's context, at the vector table.
 *   Inclusive time comes from a shadow call stack (prof_calls): a CALL/RCALL/ICALL opens a frame,
 *   its RET closes it; tail calls and jumps into another function open tail frames. A frame's
 *   time is the cycles its context counted between the two, so interrupts are left out of a
 *   main-line function's inclusive time. Main-line frames also count per caller -> callee
 *   edge, which tells who calls the float routines that LTO cannot inline.
 *   Per step, the counts gather in a sparse table (the keys touched); when the next step
 *   rises (its descriptor, written at the end of the step, is then known), the step goes into
 *   the aggregates of the kinds it belongs to: all steps, one per descriptor flag (FIX, sonar,
 *   detour planner, radio bytes), and the steps with none of the flags. The longest steps keep
 *   their own sparse tables (a min-heap of `worst_cap` steps), from which the host takes the
 *   worst 1 %. The idle fast-forward is unaffected: it skips only at WDR, with PB0 low.
 *   Cost: a dozen loads and stores per instruction inside a step; a mission's AVR simulation
 *   runs about a third slower with the profile on, and exactly as before without it (one
 *   predictable branch per instruction).
 */
#include <stdlib.h>
#include <string.h>

#include "sim_interrupts.h"

#include "unocore_prof.h"

void prof_free(prof_t *pr)
{
	free((void *)pr->func_of_word);
	free(pr->entry);
	free(pr->cur_cycles);
	free(pr->cur_calls);
	free(pr->cur_incl);
	free(pr->touched);
	free(pr->mark);
	free(pr->agg_cycles);
	free(pr->agg_calls);
	free(pr->agg_incl);
	for (uint32_t i = 0; i < pr->nheap; i++)
		free(pr->heap[i].e);
	free(pr->heap);
	memset(pr, 0, sizeof *pr);
}

static inline uint64_t worst_dur(const prof_worst *w) { return w->hdr.fall - w->hdr.rise; }

static void heap_sift_down(prof_worst *h, uint32_t n, uint32_t i)
{
	for (;;) {
		uint32_t l = 2 * i + 1, r = l + 1, m = i;
		if (l < n && worst_dur(&h[l]) < worst_dur(&h[m]))
			m = l;
		if (r < n && worst_dur(&h[r]) < worst_dur(&h[m]))
			m = r;
		if (m == i)
			return;
		prof_worst t = h[i];
		h[i] = h[m];
		h[m] = t;
		i = m;
	}
}

static void heap_sift_up(prof_worst *h, uint32_t i)
{
	while (i > 0) {
		uint32_t parent = (i - 1) / 2;
		if (worst_dur(&h[parent]) <= worst_dur(&h[i]))
			return;
		prof_worst t = h[i];
		h[i] = h[parent];
		h[parent] = t;
		i = parent;
	}
}

/* Keeps the step's table when it is among the `cap` longest so far. */
static void prof_offer_worst(prof_t *pr, const unocore_prof_step *hdr)
{
	if (pr->cap == 0)
		return;
	uint64_t dur = hdr->fall - hdr->rise;
	prof_worst *slot;
	if (pr->nheap < pr->cap) {
		slot = &pr->heap[pr->nheap];
		slot->e = NULL;
	} else if (dur > worst_dur(&pr->heap[0])) {
		slot = &pr->heap[0];
	} else {
		return;
	}
	unocore_prof_entry *e = realloc(slot->e, (pr->ntouched ? pr->ntouched : 1) * sizeof *e);
	if (!e)
		return;
	for (uint32_t i = 0; i < pr->ntouched; i++) {
		uint32_t k = pr->touched[i];
		e[i].key = k;
		e[i].cycles = pr->cur_cycles[k];
		e[i].calls = pr->cur_calls[k];
		e[i].incl = pr->cur_incl[k];
	}
	slot->e = e;
	slot->hdr = *hdr;
	slot->hdr.n = pr->ntouched;
	if (slot == &pr->heap[pr->nheap]) {
		pr->nheap++;
		heap_sift_up(pr->heap, pr->nheap - 1);
	} else {
		heap_sift_down(pr->heap, pr->nheap, 0);
	}
}

/* The step being counted has ended and its descriptor is known (the next step rose, or the
 * host asks for the figures): into the aggregates of its kinds, and maybe the worst steps. */
static void prof_finalize(prof_t *pr)
{
	if (!pr->active || pr->fall == 0)
		return;
	int kinds[PROF_KINDS], nk = 0;
	kinds[nk++] = 0;
	if (pr->has_desc) {
		for (int b = 0; b < 4; b++)
			if (pr->desc & (0x10 << b))
				kinds[nk++] = 1 + b;
		if ((pr->desc & 0xF0) == 0)
			kinds[nk++] = 5;
	}
	uint64_t dur = pr->fall - pr->rise;
	for (int j = 0; j < nk; j++) {
		int kind = kinds[j];
		uint64_t *cyc = pr->agg_cycles + (size_t)kind * pr->nkeys;
		uint64_t *cal = pr->agg_calls + (size_t)kind * pr->nkeys;
		uint64_t *inc = pr->agg_incl + (size_t)kind * pr->nkeys;
		for (uint32_t i = 0; i < pr->ntouched; i++) {
			uint32_t k = pr->touched[i];
			cyc[k] += pr->cur_cycles[k];
			cal[k] += pr->cur_calls[k];
			inc[k] += pr->cur_incl[k];
		}
		pr->info.steps[kind]++;
		pr->info.step_cycles[kind] += dur;
		pr->info.attributed[kind] += pr->attributed;
	}
	unocore_prof_step hdr = { .rise = pr->rise, .fall = pr->fall, .desc = pr->desc,
	                          .has_desc = pr->has_desc, .n = pr->ntouched };
	prof_offer_worst(pr, &hdr);
	for (uint32_t i = 0; i < pr->ntouched; i++) {
		uint32_t k = pr->touched[i];
		pr->cur_cycles[k] = 0;
		pr->cur_calls[k] = 0;
		pr->cur_incl[k] = 0;
		pr->mark[k] = 0;
	}
	pr->ntouched = 0;
	pr->active = 0;
	pr->attributed = 0;
}

/* One executed instruction (or an interrupt's entry) inside a step: `cycles` at `pc` (a byte
 * address) in interrupt context `ctx`. */
static inline void prof_count(prof_t *pr, uint32_t pc, uint32_t ctx, uint32_t cycles)
{
	uint32_t w = pc >> 1;
	uint32_t f = w < pr->nwords ? pr->func_of_word[w] : pr->nfuncs - 1;
	uint32_t key = ctx * pr->nfuncs + f;
	if (!pr->mark[key]) {
		pr->mark[key] = 1;
		pr->touched[pr->ntouched++] = key;
	}
	pr->cur_cycles[key] += cycles;
	pr->clock_all += cycles;
	if (ctx == 0)
		pr->clock_main += cycles;
	if (w < pr->nwords && pr->entry[w] && key != pr->last_key)
		pr->cur_calls[key]++;
	pr->last_key = key;
	pr->attributed += cycles;
	pr->info.instructions++;
}

static inline uint32_t prof_func(const prof_t *pr, uint32_t pc)
{
	uint32_t w = pc >> 1;
	return w < pr->nwords ? pr->func_of_word[w] : pr->nfuncs - 1;
}

static inline void prof_touch(prof_t *pr, uint32_t key)
{
	if (!pr->mark[key]) {
		pr->mark[key] = 1;
		pr->touched[pr->ntouched++] = key;
	}
}

/* A frame for function f (a CALL's target, or a tail frame's), called from function `from`. */
static inline void prof_push(prof_t *pr, uint32_t f, uint32_t ctx, int tail, uint32_t from)
{
	if (pr->depth == PROF_DEPTH) {
		pr->depth_lost++;
		return;
	}
	uint32_t key = ctx * pr->nfuncs + f;
	int nested = from == f;             /* a subroutine inside the function (avr-libc's) */
	for (uint32_t d = 0; d < pr->depth && !nested; d++)
		nested = pr->stack[d].key == key;   /* recursion: counted once, by the outer frame */
	prof_frame *fr = &pr->stack[pr->depth++];
	fr->key = key;
	fr->edge = UINT32_MAX;
	if (pr->edges && ctx == 0 && !nested) {
		fr->edge = pr->nkeys_fn + from * pr->nfuncs + f;
		prof_touch(pr, fr->edge);
		pr->cur_calls[fr->edge]++;
	}
	fr->ctx = (uint8_t)ctx;
	fr->tail = (uint8_t)tail;
	fr->nested = (uint16_t)nested;
	fr->from = from;
	fr->clock = ctx ? pr->clock_all : pr->clock_main;
}

static inline void prof_pop(prof_t *pr)
{
	prof_frame *fr = &pr->stack[--pr->depth];
	if (fr->nested)
		return;
	uint64_t now = fr->ctx ? pr->clock_all : pr->clock_main;
	uint32_t incl = (uint32_t)(now - fr->clock);
	prof_touch(pr, fr->key);
	pr->cur_incl[fr->key] += incl;
	if (fr->edge != UINT32_MAX)
		pr->cur_incl[fr->edge] += incl;   /* touched at the push */
}

/* The shadow call stack, after the instruction `op` (its second word op2) ran at pc in
 * context ctx and the PC went on to new_pc. A CALL, RCALL or ICALL opens a frame for its
 * target (decoded from the instruction, so an interrupt taken right after it changes
 * nothing); a RET closes the top frame and adds the cycles its context counted in between to
 * the callee's inclusive time, which leaves out the interrupts taken meanwhile (for a frame in
 * the main line). A RET with no frame (a call made before the step rose) is ignored. RCALL .+0
 * is not a call: GCC makes room on the stack with it, and frees the room with POP, not RET. A
 * frame whose function is already on the stack (avr-libc's routines call subroutines inside
 * themselves) adds no time: the outer frame has it.
 * Any other way into another function (a tail call, JMP/RJMP; falling through into the next
 * one, as avr-libc's float routines do; a jump into __prologue_saves__ or
 * __epilogue_restores__) opens a tail frame, closed by the next RET together with the frame
 * below it, or when the PC comes back into the function it was entered from (the prologue's
 * IJMP back into its function). RETI closes the handler's own frames. In the main line, each
 * frame also counts, and times, its edge: caller -> callee (who calls the float routines). */
static inline void prof_calls(prof_t *pr, const avr_t *avr, uint16_t op, uint16_t op2, uint32_t pc,
                              uint32_t ctx, uint32_t new_pc, int entered_isr)
{
	uint32_t target;
	if ((op & 0xF000) == 0xD000 && op != 0xD000) {         /* RCALL k (not RCALL .+0) */
		int32_t k = op & 0x0FFF;
		if (k & 0x0800)
			k -= 0x1000;
		target = (uint32_t)((int32_t)pc + 2 + 2 * k);
	} else if ((op & 0xFE0E) == 0x940E) {                  /* CALL k (two words) */
		target = ((((uint32_t)(op & 0x01F0) >> 3) | (op & 1)) << 16 | op2) * 2;
	} else if (op == 0x9509 || op == 0x9519) {             /* ICALL, EICALL: Z */
		target = (uint32_t)(avr->data[30] | avr->data[31] << 8) * 2;
	} else if (op == 0x9508) {                             /* RET */
		while (pr->depth > 0 && pr->stack[pr->depth - 1].tail)
			prof_pop(pr);
		if (pr->depth > 0)
			prof_pop(pr);
		return;
	} else if (op == 0x9518) {                             /* RETI */
		while (pr->depth > 0 && pr->stack[pr->depth - 1].ctx == ctx && ctx != 0)
			prof_pop(pr);
		return;
	} else {
		if (entered_isr)
			return;
		uint32_t f = prof_func(pr, new_pc), from = prof_func(pr, pc);
		if (f == from)
			return;
		for (uint32_t d = pr->depth; d > 0 && pr->stack[d - 1].tail; d--) {
			if (pr->stack[d - 1].from == f) {              /* back where it came from */
				while (pr->depth >= d)
					prof_pop(pr);
				return;
			}
		}
		prof_push(pr, f, ctx, 1, from);
		return;
	}
	prof_push(pr, prof_func(pr, target), ctx, 0, prof_func(pr, pc));
}

static inline uint32_t prof_ctx(const avr_t *avr)
{
	uint8_t n = avr->interrupts.running_ptr;
	if (n == 0 || !avr->interrupts.running[n - 1])
		return 0;
	return avr->interrupts.running[n - 1]->vector & (PROF_CTX - 1);
}

/* ------------------------------------------------------------------------------ the steps */

void prof_step_rise(prof_t *pr, uint64_t now, uint32_t boot)
{
	prof_finalize(pr);   /* the previous step's descriptor came before this edge */
	pr->active = 1;
	pr->rise = now;
	pr->fall = 0;
	pr->desc = 0;
	pr->has_desc = 0;
	pr->boot = boot;
	pr->attributed = 0;
	pr->depth = 0;
}

void prof_step_fall(prof_t *pr, uint64_t now)
{
	if (pr->active && pr->fall == 0) {
		pr->fall = now;
		pr->info.open_frames += pr->depth;
	}
}

void prof_step_desc(prof_t *pr, uint8_t desc, uint32_t boot)
{
	if (pr->active && pr->boot == boot) {
		pr->desc = desc;
		pr->has_desc = 1;
	}
}

void prof_step_cut(prof_t *pr, uint64_t now)
{
	if (pr->active && pr->fall == 0)
		pr->fall = now;
}

/* Inside a step: counts this instruction's cycles where it ran (see the top of the file). */
int prof_run(prof_t *pr, avr_t *avr)
{
	avr_cycle_count_t c0 = avr->cycle;
	uint32_t pc0 = avr->pc;
	uint8_t depth0 = avr->interrupts.running_ptr;
	uint32_t ctx0 = prof_ctx(avr);
	uint16_t op = 0, op2 = 0;
	if (pc0 + 3 <= avr->flashend) {
		op = (uint16_t)(avr->flash[pc0] | avr->flash[pc0 + 1] << 8);
		op2 = (uint16_t)(avr->flash[pc0 + 2] | avr->flash[pc0 + 3] << 8);
	}
	int state = avr_run(avr);
	if (avr->cycle > c0 && pr->active) {
		uint32_t dc = (uint32_t)(avr->cycle - c0);
		if (avr->interrupts.running_ptr > depth0) /* an interrupt's entry */
			prof_count(pr, avr->pc, prof_ctx(avr), dc);
		else
			prof_count(pr, pc0, ctx0, dc);
		prof_calls(pr, avr, op, op2, pc0, ctx0, avr->pc, avr->interrupts.running_ptr > depth0);
	}
	return state;
}

/* ------------------------------------------------------------------------------ the host's side */

int prof_start(prof_t *pr, const uint16_t *func_of_word, uint32_t nwords, const uint8_t *entry,
               uint32_t nfuncs, uint32_t worst_cap)
{
	prof_free(pr);
	if (nfuncs == 0 || (uint64_t)nfuncs * PROF_CTX > UINT32_MAX / 2)
		return -1;
	for (uint32_t i = 0; i < nwords; i++)
		if (func_of_word[i] >= nfuncs)
			return -1;
	pr->nwords = nwords;
	pr->nfuncs = nfuncs;
	pr->nkeys_fn = nfuncs * PROF_CTX;
	pr->edges = nfuncs <= 512;          /* nfuncs^2 edges: up to 256K keys (the image: ~140) */
	pr->nkeys = pr->nkeys_fn + (pr->edges ? nfuncs * nfuncs : 0);
	uint16_t *map = malloc((nwords ? nwords : 1) * sizeof *map);
	pr->entry = calloc(nwords ? nwords : 1, 1);
	pr->cur_cycles = calloc(pr->nkeys, sizeof *pr->cur_cycles);
	pr->cur_calls = calloc(pr->nkeys, sizeof *pr->cur_calls);
	pr->cur_incl = calloc(pr->nkeys, sizeof *pr->cur_incl);
	pr->touched = malloc(pr->nkeys * sizeof *pr->touched);
	pr->mark = calloc(pr->nkeys, 1);
	pr->agg_cycles = calloc((size_t)PROF_KINDS * pr->nkeys, sizeof *pr->agg_cycles);
	pr->agg_calls = calloc((size_t)PROF_KINDS * pr->nkeys, sizeof *pr->agg_calls);
	pr->agg_incl = calloc((size_t)PROF_KINDS * pr->nkeys, sizeof *pr->agg_incl);
	pr->cap = worst_cap;
	pr->heap = calloc(worst_cap ? worst_cap : 1, sizeof *pr->heap);
	pr->func_of_word = map;
	if (!map || !pr->entry || !pr->cur_cycles || !pr->cur_calls || !pr->cur_incl ||
	    !pr->touched || !pr->mark || !pr->agg_cycles || !pr->agg_calls || !pr->agg_incl || !pr->heap) {
		prof_free(pr);
		return -1;
	}
	memcpy(map, func_of_word, nwords * sizeof *map);
	memcpy(pr->entry, entry, nwords);
	pr->last_key = UINT32_MAX;
	pr->info.nfuncs = nfuncs;
	pr->info.nctx = PROF_CTX;
	pr->info.nkeys = pr->nkeys;
	pr->info.nedges = pr->nkeys - pr->nkeys_fn;
	pr->info.nkinds = PROF_KINDS;
	pr->info.worst_cap = worst_cap;
	pr->on = 1;
	return 0;
}

void prof_info_read(prof_t *pr, unocore_prof_info *out)
{
	prof_finalize(pr);
	pr->info.worst_kept = pr->nheap;
	pr->info.unfinished = (uint32_t)pr->active;
	pr->info.depth_lost = pr->depth_lost;
	*out = pr->info;
}

uint32_t prof_read(prof_t *pr, uint32_t kind, uint64_t *cycles, uint64_t *calls, uint64_t *incl,
                   uint32_t max)
{
	if (!pr->on || kind >= PROF_KINDS || max < pr->nkeys)
		return 0;
	prof_finalize(pr);
	memcpy(cycles, pr->agg_cycles + (size_t)kind * pr->nkeys, pr->nkeys * sizeof *cycles);
	memcpy(calls, pr->agg_calls + (size_t)kind * pr->nkeys, pr->nkeys * sizeof *calls);
	memcpy(incl, pr->agg_incl + (size_t)kind * pr->nkeys, pr->nkeys * sizeof *incl);
	return pr->nkeys;
}

uint32_t prof_worst_read(const prof_t *pr, uint32_t i, unocore_prof_step *hdr,
                         unocore_prof_entry *out, uint32_t max)
{
	if (i >= pr->nheap)
		return 0;
	*hdr = pr->heap[i].hdr;
	uint32_t n = hdr->n < max ? hdr->n : max;
	memcpy(out, pr->heap[i].e, n * sizeof *out);
	return n;
}
