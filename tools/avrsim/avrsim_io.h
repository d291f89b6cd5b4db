/*
 * avrsim_io.h: the outside end of rovernav_avrsim's UART0 bridge: a pseudo-terminal or
 * stdin/stdout, the two byte rings between it and the line into the AVR (uart_line.c), and
 * their service between simulation slices (avrsim_io.c). rovernav_avrsim.c has the timing
 * model and the command line.
 */
#ifndef ROVERNAV_AVRSIM_IO_H
#define ROVERNAV_AVRSIM_IO_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "uart_line.h"

#define PROG "rovernav_avrsim"
#define RING_BYTES (64u * 1024u)

typedef struct ring {
	uint8_t buf[RING_BYTES];
	size_t head; /* index of the oldest byte */
	size_t len;
} ring_t;


enum mode { MODE_PTY, MODE_STDIO };

typedef struct bridge_io {
	enum mode mode;
	int verbose;
	uart_line_t *uart;              /* kicked when bytes for the AVR arrive */
	volatile sig_atomic_t *stop;    /* set by a signal: a blocked write gives up */

	int in_fd;
	int out_fd;
	int pty_slave_fd;        /* held open so the pty never hangs up between clients */
	int in_eof;
	ring_t in;
	ring_t out;

	uint64_t bytes_dropped_out;     /* from the AVR, nobody reading (--pty) */
} bridge_io_t;

/* "rovernav_avrsim: ..." and a newline, on stderr. */
void logmsg(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* The line's callbacks (uart_line_t .waiting, .take, .sent), with the bridge_io_t as .user. */
uint32_t io_uart_waiting(void *param);
uint8_t io_uart_take(void *param);
void io_uart_sent(void *param, uint8_t byte);

/* Opens the pty (prints "pty: PATH" on stdout, then sends stdout to stderr) or takes stdin and
 * stdout as the byte stream. Returns 0, or -1 (logged). */
int io_open_pty(bridge_io_t *io);
int io_open_stdio(bridge_io_t *io);

/* Writes what it can of the output ring; block != 0 waits until the ring is empty.
 * Returns -1 when the reader is gone (EPIPE), 0 otherwise. */
int io_flush_output(bridge_io_t *io, int block);

/* Services the outside world, waiting at most timeout seconds for something to do
 * (timeout <= 0: just poll). Returns -1 when the bridge should stop. */
int io_service(bridge_io_t *io, double timeout);

#endif /* ROVERNAV_AVRSIM_IO_H */
