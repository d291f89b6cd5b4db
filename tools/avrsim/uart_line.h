/*
 * uart_line.h: the serial line into an AVR's UART that both simavr harnesses share:
 * rovernav_avrsim.c (the pty bridge of `rovernav demo`) and unocore.c (the Uno of
 * `rovernav sim --rover uno`, host/rovernav/cores/uno.py).
 *
 *   Bytes from the outside wait in the harness's own queue and enter the simulated UART from a
 *   cycle timer, at most one byte per byte-time of the line (10 bits, 8N1, at the baud rate:
 *   2,778 cycles at 57,600 baud and 16 MHz), and only while the UART says it has room (its
 *   XON/XOFF IRQs), so no byte is lost inside the simulated UART.
 *
 *   Bytes the AVR writes to UDR go to the harness's `sent` callback as they are written
 *   (simavr already paces them at the configured baud rate).
 *
 * The functions are in uart_line.c.
 *
 *   uart_line_t line = { .user = h, .waiting = ..., .take = ..., .sent = ... };
 *   uart_line_attach(&line, avr, '0', baud);   once the firmware is loaded
 *   uart_line_kick(&line);                     after queueing bytes for the UART
 *   uart_line_after_reset(&line);              after avr_reset (simavr cleared the cycle timers)
 */
#ifndef ROVERNAV_UART_LINE_H
#define ROVERNAV_UART_LINE_H

#include <stdint.h>

#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_cycle_timers.h"
#include "sim_io.h"
#include "sim_irq.h"

#define UART_LINE_BITS_PER_BYTE 10u   /* 8N1: start, 8 data, stop */

typedef struct uart_line {
	/* the harness's side, set before uart_line_attach */
	void *user;
	uint32_t (*waiting)(void *user);          /* bytes queued for the UART */
	uint8_t (*take)(void *user);              /* the oldest of them (called only when waiting) */
	void (*sent)(void *user, uint8_t byte);   /* a byte the AVR wrote to UDR */

	/* the line's state */
	avr_t *avr;
	avr_irq_t *in;                            /* UART_IRQ_INPUT: a byte into the receiver */
	avr_cycle_count_t cycles_per_byte;        /* one byte-time of the line */
	avr_cycle_count_t last_feed_cycle;        /* when the last byte went in */
	int armed;                                /* the feed timer is registered */
	int ready;                                /* XON seen and no XOFF since */

	/* counters */
	uint64_t bytes_in;                        /* fed to the UART */
	uint64_t bytes_out;                       /* written by the AVR */
	uint64_t xoffs;                           /* times the UART's input FIFO filled up */
} uart_line_t;

/* Connects the line to UART `name` ('0') of `avr`, at `baud`: no console echo of its output,
 * no usleep() when the firmware polls UCSRnA. Returns 0, or -1 when the MCU has no such UART. */
int uart_line_attach(uart_line_t *l, avr_t *avr, char name, uint32_t baud);

/* Bytes are waiting: feed them from one byte-time after the last one went in (at once if that
 * has passed), unless the feed timer is already running. */
void uart_line_kick(uart_line_t *l);

/* After a reset: simavr cleared the cycle timers (the feed's among them) and possibly the cycle
 * counter, and the UART waits for its receiver to be enabled again (XON). */
void uart_line_after_reset(uart_line_t *l);

#endif /* ROVERNAV_UART_LINE_H */
