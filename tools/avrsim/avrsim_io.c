/*
 * avrsim_io.c: the outside end of rovernav_avrsim's UART0 bridge (avrsim_io.h). Bytes from the
 * outside wait in the input ring until the line (uart_line.c) feeds them to the AVR; when the
 * ring is full the bridge stops reading, and the kernel's pty/pipe buffer holds the rest. Bytes
 * the AVR sends wait in the output ring for the reader: with --pty, if nobody reads the pty and
 * the ring fills up, further bytes are dropped and counted, as on a serial line nobody listens
 * to; with --stdio, the simulation waits for the reader instead.
 */
#define _GNU_SOURCE

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "avrsim_io.h"

#define IO_CHUNK 512u

/* ------------------------------------------------------------------------------ byte rings */

static size_t ring_space(const ring_t *r) { return RING_BYTES - r->len; }

static void ring_push(ring_t *r, uint8_t b)
{
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

/* The longest run of queued bytes that is contiguous in memory, at most max. */
static size_t ring_peek(const ring_t *r, const uint8_t **data, size_t max)
{
	size_t n = RING_BYTES - r->head;
	if (n > r->len)
		n = r->len;
	if (n > max)
		n = max;
	*data = r->buf + r->head;
	return n;
}

static void ring_drop(ring_t *r, size_t n)
{
	r->head = (r->head + n) % RING_BYTES;
	r->len -= n;
}

void logmsg(const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fputs(PROG ": ", stderr);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
}

/* ------------------------------------------------------------------------------ UART hooks */

/* Every byte the firmware writes to UDR0 (the line's `sent`). */
void io_uart_sent(void *param, uint8_t byte)
{
	bridge_io_t *io = param;
	if (ring_space(&io->out) == 0 && io->mode == MODE_STDIO)
		io_flush_output(io, 1); /* a pipe reader is slow: wait for it rather than lose bytes */
	if (ring_space(&io->out) == 0) {
		io->bytes_dropped_out++;
		return;
	}
	ring_push(&io->out, byte);
}

/* The bytes from the outside waiting for the UART, and the oldest of them (the line's). */
uint32_t io_uart_waiting(void *param)
{
	return (uint32_t)((bridge_io_t *)param)->in.len;
}

uint8_t io_uart_take(void *param)
{
	return ring_pop(&((bridge_io_t *)param)->in);
}

/* ------------------------------------------------------------------------------ outside I/O */

/* Writes what it can of the output ring; block != 0 waits until the ring is empty.
 * Returns -1 when the reader is gone (EPIPE), 0 otherwise. */
int io_flush_output(bridge_io_t *io, int block)
{
	while (io->out.len > 0) {
		if (block) {
			struct pollfd p = { .fd = io->out_fd, .events = POLLOUT };
			if (poll(&p, 1, -1) < 0 && errno != EINTR)
				return -1;
			if (*io->stop)
				return 0;
		}
		const uint8_t *data;
		size_t n = ring_peek(&io->out, &data, IO_CHUNK);
		ssize_t w = write(io->out_fd, data, n);
		if (w > 0) {
			ring_drop(&io->out, (size_t)w);
			continue;
		}
		if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
			if (!block)
				return 0;
			continue;
		}
		if (w < 0 && errno == EPIPE)
			return -1;
		if (w < 0) {
			logmsg("write: %s", strerror(errno));
			return -1;
		}
	}
	return 0;
}

/* Reads what is waiting on the input into the input ring. Returns -1 on a fatal error. */
static int read_input(bridge_io_t *io)
{
	uint8_t buf[IO_CHUNK];
	size_t room = ring_space(&io->in);
	if (room == 0 || io->in_eof)
		return 0;
	if (room > sizeof buf)
		room = sizeof buf;
	ssize_t r = read(io->in_fd, buf, room);
	if (r > 0) {
		for (ssize_t i = 0; i < r; i++)
			ring_push(&io->in, buf[i]);
		uart_line_kick(io->uart);
		return 0;
	}
	if (r == 0) {
		/* stdin closed: keep running, the firmware may still talk */
		if (io->mode == MODE_STDIO) {
			if (io->verbose)
				logmsg("stdin closed; running on");
			io->in_eof = 1;
		}
		return 0;
	}
	if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)
		return 0;
	if (errno == EIO && io->mode == MODE_PTY)
		return 0; /* no client on the pty right now */
	logmsg("read: %s", strerror(errno));
	return -1;
}

/* Services the outside world, waiting at most timeout seconds for something to do
 * (timeout <= 0: just poll). Returns -1 when the bridge should stop. */
int io_service(bridge_io_t *io, double timeout)
{
	struct pollfd p[2];
	int n = 0;
	int in_ix = -1, out_ix = -1;

	if (!io->in_eof && ring_space(&io->in) > 0) {
		in_ix = n;
		p[n++] = (struct pollfd){ .fd = io->in_fd, .events = POLLIN };
	}
	if (io->out.len > 0) {
		if (io->out_fd == io->in_fd && in_ix >= 0) {
			p[in_ix].events |= POLLOUT;
			out_ix = in_ix;
		} else {
			out_ix = n;
			p[n++] = (struct pollfd){ .fd = io->out_fd, .events = POLLOUT };
		}
	}
	struct timespec ts = { 0, 0 };
	if (timeout > 0) {
		ts.tv_sec = (time_t)timeout;
		ts.tv_nsec = (long)((timeout - (double)ts.tv_sec) * 1e9);
	}
	int rc = ppoll(p, (nfds_t)n, &ts, NULL);
	if (rc < 0)
		return errno == EINTR ? 0 : -1;
	if (rc == 0)
		return 0;
	if (in_ix >= 0 && (p[in_ix].revents & (POLLIN | POLLHUP | POLLERR))) {
		if (read_input(io) < 0)
			return -1;
	}
	if (out_ix >= 0 && (p[out_ix].revents & (POLLOUT | POLLERR))) {
		if (io_flush_output(io, 0) < 0) {
			logmsg("output closed by the reader");
			return -1;
		}
	}
	return 0;
}

/* ------------------------------------------------------------------------------ setup */

int io_open_pty(bridge_io_t *io)
{
	int master = posix_openpt(O_RDWR | O_NOCTTY);
	if (master < 0) {
		logmsg("posix_openpt: %s", strerror(errno));
		return -1;
	}
	if (grantpt(master) < 0 || unlockpt(master) < 0) {
		logmsg("grantpt/unlockpt: %s", strerror(errno));
		close(master);
		return -1;
	}
	const char *name = ptsname(master);
	if (!name) {
		logmsg("ptsname: %s", strerror(errno));
		close(master);
		return -1;
	}
	int slave = open(name, O_RDWR | O_NOCTTY);
	if (slave < 0) {
		logmsg("open %s: %s", name, strerror(errno));
		close(master);
		return -1;
	}
	struct termios t;
	if (tcgetattr(slave, &t) == 0) {
		cfmakeraw(&t);
		cfsetispeed(&t, B57600);
		cfsetospeed(&t, B57600);
		tcsetattr(slave, TCSANOW, &t);
	}
	fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
	io->in_fd = io->out_fd = master;
	io->pty_slave_fd = slave;

	printf("pty: %s\n", name);
	fflush(stdout);
	/* anything the library might print from now on goes to stderr */
	dup2(STDERR_FILENO, STDOUT_FILENO);
	return 0;
}

int io_open_stdio(bridge_io_t *io)
{
	io->in_fd = STDIN_FILENO;
	io->out_fd = dup(STDOUT_FILENO); /* the data stream */
	if (io->out_fd < 0) {
		logmsg("dup: %s", strerror(errno));
		return -1;
	}
	/* stray library output must not corrupt the byte stream */
	dup2(STDERR_FILENO, STDOUT_FILENO);
	return 0;
}
