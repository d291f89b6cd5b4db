/*
 * rovernav_avrsim: runs the rover's Uno image (an AVR ELF) in simavr and bridges UART0 to a
 * pseudo-terminal or to stdin/stdout, so host code talks to the compiled firmware exactly as
 * it would talk to the radio on /dev/ttyUSB0.
 *
 *   rovernav_avrsim [--pty | --stdio] [--speed X] [--seconds N] [--vcd FILE] firmware.elf
 *
 * Timing model
 *   The simulation advances in slices of 1 ms of simulated time. Between slices the bridge
 *   moves bytes between the outside world and two rings, and (for --speed X > 0) waits until
 *   the wall clock has caught up with simulated time / X. --speed 0 never waits.
 *
 *   Bytes from the outside enter the simulated UART from a cycle timer, at most one byte per
 *   byte-time of the line (10 bits at --baud, default 57,600: ~174 us, 2,778 cycles at 16 MHz)
 *   and only while the UART says it has room (its XON/XOFF IRQs), so no byte is lost inside
 *   the simulated UART (uart_line.h, the line model unocore.c uses too). When the input ring is
 *   full the bridge stops reading its input, and the kernel's pty/pipe buffer holds the rest.
 *
 *   Bytes the AVR sends go out as they are written to UDR0 (simavr already paces them at the
 *   configured baud rate). With --pty, if nobody reads the pty and the output ring fills up,
 *   further bytes are dropped and counted, as on a serial line nobody listens to. With --stdio,
 *   the simulation waits for the reader instead.
 *
 * Exit status: 0 after a clean stop (--seconds reached, SIGINT/SIGTERM/SIGHUP, the AVR went to
 * sleep with interrupts off, stdout closed); 1 if the simulated core crashed; 2 on a usage or
 * load error.
 */
#define _GNU_SOURCE

#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <inttypes.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "avr_ioport.h"
#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_irq.h"
#include "sim_vcd_file.h"

#include "uart_line.h"

#define PROG "rovernav_avrsim"
#define DEFAULT_MCU "atmega328p"
#define DEFAULT_FREQ_HZ 16000000u
#define DEFAULT_BAUD 57600u
#define UART_NAME '0'
#define RING_BYTES (64u * 1024u)
#define IO_CHUNK 512u
#define SLICE_PER_SECOND 1000u       /* simulate in 1 ms slices */
#define MAX_LAG_SECONDS 0.1          /* further behind than this: stop catching up */

/* ------------------------------------------------------------------------------ byte rings */

typedef struct ring {
	uint8_t buf[RING_BYTES];
	size_t head; /* index of the oldest byte */
	size_t len;
} ring_t;

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

/* ------------------------------------------------------------------------------ state */

enum mode { MODE_PTY, MODE_STDIO };

static struct {
	/* options */
	enum mode mode;
	double speed;
	double seconds;          /* <= 0: no limit */
	const char *vcd_path;
	const char *elf_path;
	const char *mcu_default;
	uint32_t freq_default;
	uint32_t baud;
	int verbose;

	/* simulation */
	avr_t *avr;
	uart_line_t uart;        /* UART0 (uart_line.h): input paced at the line's rate */
	avr_vcd_t vcd;
	int vcd_open;

	/* the outside world */
	int in_fd;
	int out_fd;
	int pty_slave_fd;        /* held open so the pty never hangs up between clients */
	int in_eof;
	ring_t in;
	ring_t out;

	/* counters (bytes to and from the AVR, XOFFs: the line's) */
	uint64_t bytes_dropped_out;
} g = {
	.mode = MODE_PTY,
	.speed = 1.0,
	.seconds = 0.0,
	.mcu_default = DEFAULT_MCU,
	.freq_default = DEFAULT_FREQ_HZ,
	.baud = DEFAULT_BAUD,
	.in_fd = -1,
	.out_fd = -1,
	.pty_slave_fd = -1,
};

static volatile sig_atomic_t g_stop_signal = 0;

static void logmsg(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static void logmsg(const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fputs(PROG ": ", stderr);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
}

/* simavr logs to stdout by default, which is our data stream with --stdio: send it to stderr. */
static void sim_logger(avr_t *avr, const int level, const char *fmt, va_list ap)
{
	int wanted = avr ? avr->log : LOG_ERROR;
	if (level > wanted)
		return;
	fputs("simavr: ", stderr);
	vfprintf(stderr, fmt, ap);
}

static void on_signal(int sig) { g_stop_signal = sig; }

static double now_seconds(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static const char *state_name(int state)
{
	switch (state) {
	case cpu_Limbo: return "limbo";
	case cpu_Stopped: return "stopped";
	case cpu_Running: return "running";
	case cpu_Sleeping: return "sleeping";
	case cpu_Step: return "step";
	case cpu_StepDone: return "step-done";
	case cpu_Done: return "done (sleeping with interrupts off)";
	case cpu_Crashed: return "CRASHED";
	default: return "unknown";
	}
}

/* ------------------------------------------------------------------------------ UART hooks */

static int flush_output(int block);

/* Every byte the firmware writes to UDR0 (the line's `sent`). */
static void uart_sent(void *param, uint8_t byte)
{
	(void)param;
	if (ring_space(&g.out) == 0 && g.mode == MODE_STDIO)
		flush_output(1); /* a pipe reader is slow: wait for it rather than lose bytes */
	if (ring_space(&g.out) == 0) {
		g.bytes_dropped_out++;
		return;
	}
	ring_push(&g.out, byte);
}

/* The bytes from the outside waiting for the UART, and the oldest of them (the line's). */
static uint32_t uart_waiting(void *param)
{
	(void)param;
	return (uint32_t)g.in.len;
}

static uint8_t uart_take(void *param)
{
	(void)param;
	return ring_pop(&g.in);
}

/* ------------------------------------------------------------------------------ outside I/O */

/* Writes what it can of the output ring; block != 0 waits until the ring is empty.
 * Returns -1 when the reader is gone (EPIPE), 0 otherwise. */
static int flush_output(int block)
{
	while (g.out.len > 0) {
		if (block) {
			struct pollfd p = { .fd = g.out_fd, .events = POLLOUT };
			if (poll(&p, 1, -1) < 0 && errno != EINTR)
				return -1;
			if (g_stop_signal)
				return 0;
		}
		const uint8_t *data;
		size_t n = ring_peek(&g.out, &data, IO_CHUNK);
		ssize_t w = write(g.out_fd, data, n);
		if (w > 0) {
			ring_drop(&g.out, (size_t)w);
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
static int read_input(void)
{
	uint8_t buf[IO_CHUNK];
	size_t room = ring_space(&g.in);
	if (room == 0 || g.in_eof)
		return 0;
	if (room > sizeof buf)
		room = sizeof buf;
	ssize_t r = read(g.in_fd, buf, room);
	if (r > 0) {
		for (ssize_t i = 0; i < r; i++)
			ring_push(&g.in, buf[i]);
		uart_line_kick(&g.uart);
		return 0;
	}
	if (r == 0) {
		/* stdin closed: keep running, the firmware may still talk */
		if (g.mode == MODE_STDIO) {
			if (g.verbose)
				logmsg("stdin closed; running on");
			g.in_eof = 1;
		}
		return 0;
	}
	if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)
		return 0;
	if (errno == EIO && g.mode == MODE_PTY)
		return 0; /* no client on the pty right now */
	logmsg("read: %s", strerror(errno));
	return -1;
}

/* Services the outside world, waiting at most timeout seconds for something to do
 * (timeout <= 0: just poll). Returns -1 when the bridge should stop. */
static int service_io(double timeout)
{
	struct pollfd p[2];
	int n = 0;
	int in_ix = -1, out_ix = -1;

	if (!g.in_eof && ring_space(&g.in) > 0) {
		in_ix = n;
		p[n++] = (struct pollfd){ .fd = g.in_fd, .events = POLLIN };
	}
	if (g.out.len > 0) {
		if (g.out_fd == g.in_fd && in_ix >= 0) {
			p[in_ix].events |= POLLOUT;
			out_ix = in_ix;
		} else {
			out_ix = n;
			p[n++] = (struct pollfd){ .fd = g.out_fd, .events = POLLOUT };
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
		if (read_input() < 0)
			return -1;
	}
	if (out_ix >= 0 && (p[out_ix].revents & (POLLOUT | POLLERR))) {
		if (flush_output(0) < 0) {
			logmsg("output closed by the reader");
			return -1;
		}
	}
	return 0;
}

/* ------------------------------------------------------------------------------ setup */

static int open_pty(void)
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
	g.in_fd = g.out_fd = master;
	g.pty_slave_fd = slave;

	printf("pty: %s\n", name);
	fflush(stdout);
	/* anything the library might print from now on goes to stderr */
	dup2(STDERR_FILENO, STDOUT_FILENO);
	return 0;
}

static int open_stdio(void)
{
	g.in_fd = STDIN_FILENO;
	g.out_fd = dup(STDOUT_FILENO); /* the data stream */
	if (g.out_fd < 0) {
		logmsg("dup: %s", strerror(errno));
		return -1;
	}
	/* stray library output must not corrupt the byte stream */
	dup2(STDERR_FILENO, STDOUT_FILENO);
	return 0;
}

static void add_vcd_signal(avr_irq_t *irq, int bits, const char *name)
{
	if (irq)
		avr_vcd_add_signal(&g.vcd, irq, bits, name);
}

static int setup_vcd(void)
{
	if (avr_vcd_init(g.avr, g.vcd_path, &g.vcd, 1000 /* us between flushes */) != 0) {
		logmsg("cannot start VCD file %s", g.vcd_path);
		return -1;
	}
	add_vcd_signal(avr_io_getirq(g.avr, AVR_IOCTL_UART_GETIRQ(UART_NAME), UART_IRQ_OUTPUT),
	               8, "uart0_tx_byte");
	add_vcd_signal(avr_io_getirq(g.avr, AVR_IOCTL_UART_GETIRQ(UART_NAME), UART_IRQ_INPUT),
	               8, "uart0_rx_byte");
	add_vcd_signal(avr_io_getirq(g.avr, AVR_IOCTL_IOPORT_GETIRQ('B'), IOPORT_IRQ_PIN_ALL),
	               8, "portb");
	add_vcd_signal(avr_io_getirq(g.avr, AVR_IOCTL_IOPORT_GETIRQ('C'), IOPORT_IRQ_PIN_ALL),
	               8, "portc");
	add_vcd_signal(avr_io_getirq(g.avr, AVR_IOCTL_IOPORT_GETIRQ('D'), IOPORT_IRQ_PIN_ALL),
	               8, "portd");
	avr_vcd_start(&g.vcd);
	g.vcd_open = 1;
	return 0;
}

static void no_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
	/* pacing against the wall clock is done between slices, not here */
	(void)avr;
	(void)how_long;
}

static int load_avr(void)
{
	static elf_firmware_t fw; /* large: keep it off the stack */
	memset(&fw, 0, sizeof fw);
	if (elf_read_firmware(g.elf_path, &fw) != 0) {
		logmsg("cannot read firmware %s", g.elf_path);
		return -1;
	}
	if (fw.flash == NULL || fw.flashsize == 0) {
		logmsg("%s holds no program for the flash (is it an AVR ELF?)", g.elf_path);
		return -1;
	}
	if (fw.mmcu[0] == '\0')
		snprintf(fw.mmcu, sizeof fw.mmcu, "%s", g.mcu_default);
	if (fw.frequency == 0)
		fw.frequency = g.freq_default;

	g.avr = avr_make_mcu_by_name(fw.mmcu);
	if (!g.avr) {
		logmsg("simavr does not know the MCU '%s'", fw.mmcu);
		return -1;
	}
	avr_init(g.avr);
	g.avr->log = g.verbose ? LOG_TRACE : LOG_WARNING;
	avr_load_firmware(g.avr, &fw);
	g.avr->sleep = no_sleep;

	/* no console echo of UART output, no usleep() when the firmware polls UCSR0A */
	g.uart = (uart_line_t){.waiting = uart_waiting, .take = uart_take, .sent = uart_sent};
	if (uart_line_attach(&g.uart, g.avr, UART_NAME, g.baud) != 0) {
		logmsg("MCU %s has no UART%c", fw.mmcu, UART_NAME);
		return -1;
	}
	logmsg("%s: %s at %" PRIu32 " Hz, UART%c input paced at %" PRIu64 " cycles/byte (%u baud)",
	       g.elf_path, fw.mmcu, g.avr->frequency, UART_NAME, (uint64_t)g.uart.cycles_per_byte, g.baud);
	return 0;
}

/* ------------------------------------------------------------------------------ main */

static void usage(FILE *to)
{
	fprintf(to,
	        "usage: " PROG " [--pty | --stdio] [--speed X] [--seconds N] [--vcd FILE]\n"
	        "                       [--baud B] [--mcu NAME] [--freq HZ] [-v] firmware.elf\n"
	        "\n"
	        "Runs an AVR firmware image in simavr and bridges its UART0 to the outside.\n"
	        "  --pty         open a pseudo-terminal; its path is printed first on stdout as\n"
	        "                'pty: /dev/pts/N' (default)\n"
	        "  --stdio       use stdin/stdout as the byte stream (binary); logs on stderr\n"
	        "  --speed X     run at X times real time (default 1); 0 = as fast as possible\n"
	        "  --seconds N   stop after N simulated seconds (default: run until stopped)\n"
	        "  --vcd FILE    trace UART0 bytes and ports B, C, D to a VCD file\n"
	        "  --baud B      line rate used to pace bytes into the UART (default 57600)\n"
	        "  --mcu NAME    MCU when the ELF does not say (default atmega328p)\n"
	        "  --freq HZ     clock when the ELF does not say (default 16000000)\n"
	        "  -v            verbose: simavr trace messages\n");
}

static int parse_double(const char *s, double *out)
{
	char *end;
	errno = 0;
	double v = strtod(s, &end);
	if (errno || end == s || *end != '\0' || !isfinite(v) || v < 0)
		return -1;
	*out = v;
	return 0;
}

static int parse_args(int argc, char **argv)
{
	static const struct option opts[] = {
		{ "pty", no_argument, NULL, 'p' },
		{ "stdio", no_argument, NULL, 's' },
		{ "speed", required_argument, NULL, 'x' },
		{ "seconds", required_argument, NULL, 'n' },
		{ "vcd", required_argument, NULL, 'c' },
		{ "baud", required_argument, NULL, 'b' },
		{ "mcu", required_argument, NULL, 'm' },
		{ "freq", required_argument, NULL, 'f' },
		{ "verbose", no_argument, NULL, 'v' },
		{ "help", no_argument, NULL, 'h' },
		{ NULL, 0, NULL, 0 },
	};
	int c;
	double v;
	while ((c = getopt_long(argc, argv, "vh", opts, NULL)) != -1) {
		switch (c) {
		case 'p': g.mode = MODE_PTY; break;
		case 's': g.mode = MODE_STDIO; break;
		case 'x':
			if (parse_double(optarg, &g.speed) != 0) {
				logmsg("--speed wants a number >= 0, not '%s'", optarg);
				return -1;
			}
			break;
		case 'n':
			if (parse_double(optarg, &g.seconds) != 0 || g.seconds == 0) {
				logmsg("--seconds wants a number > 0, not '%s'", optarg);
				return -1;
			}
			break;
		case 'c': g.vcd_path = optarg; break;
		case 'b':
			if (parse_double(optarg, &v) != 0 || v < 300 || v > 4e6) {
				logmsg("--baud wants a rate in 300..4000000, not '%s'", optarg);
				return -1;
			}
			g.baud = (uint32_t)v;
			break;
		case 'm': g.mcu_default = optarg; break;
		case 'f':
			if (parse_double(optarg, &v) != 0 || v < 1000 || v > 1e9) {
				logmsg("--freq wants a clock in Hz, not '%s'", optarg);
				return -1;
			}
			g.freq_default = (uint32_t)v;
			break;
		case 'v': g.verbose = 1; break;
		case 'h': usage(stdout); exit(0);
		default: usage(stderr); return -1;
		}
	}
	if (optind != argc - 1) {
		usage(stderr);
		return -1;
	}
	g.elf_path = argv[optind];
	return 0;
}

int main(int argc, char **argv)
{
	if (parse_args(argc, argv) != 0)
		return 2;

	avr_global_logger_set(sim_logger);

	struct sigaction sa;
	memset(&sa, 0, sizeof sa);
	sa.sa_handler = on_signal;
	sigemptyset(&sa.sa_mask);
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);
	sigaction(SIGHUP, &sa, NULL);
	signal(SIGPIPE, SIG_IGN);

	/* load before opening the pty, so a bad ELF fails before anyone connects */
	if (load_avr() != 0)
		return 2;
	if (g.vcd_path && setup_vcd() != 0)
		return 2;
	if ((g.mode == MODE_PTY ? open_pty() : open_stdio()) != 0)
		return 2;

	avr_t *avr = g.avr;
	const double freq = (double)avr->frequency;
	const avr_cycle_count_t slice = avr->frequency / SLICE_PER_SECOND;
	const avr_cycle_count_t start_cycle = avr->cycle;
	const avr_cycle_count_t limit =
	        g.seconds > 0 ? start_cycle + (avr_cycle_count_t)llround(g.seconds * freq) : 0;
	const char *reason = NULL;
	int state = avr->state;
	int exit_code = 0;

	const double wall_start = now_seconds();
	double pace_wall = wall_start;           /* wall time when pace_cycle was simulated */
	avr_cycle_count_t pace_cycle = start_cycle;

	while (!reason) {
		avr_cycle_count_t target = avr->cycle + slice;
		if (limit && target > limit)
			target = limit;
		while (avr->cycle < target) {
			state = avr_run(avr);
			if (state == cpu_Done || state == cpu_Crashed || state == cpu_Stopped)
				break;
		}
		if (state == cpu_Crashed) {
			reason = "the AVR core crashed";
			exit_code = 1;
		} else if (state == cpu_Done) {
			reason = "the AVR went to sleep with interrupts off";
		} else if (state == cpu_Stopped) {
			reason = "the AVR core stopped";
		} else if (limit && avr->cycle >= limit) {
			reason = "time limit reached";
		} else if (g_stop_signal) {
			reason = strsignal(g_stop_signal);
		}

		/* move bytes; with --speed X, wait for the wall clock while doing so */
		if (service_io(0) < 0 && !reason)
			reason = "I/O closed";
		if (g.speed > 0 && !reason) {
			for (;;) {
				double due = pace_wall + (double)(avr->cycle - pace_cycle) / freq / g.speed;
				double wait = due - now_seconds();
				if (wait < -MAX_LAG_SECONDS) { /* too far behind: don't sprint to catch up */
					pace_wall = now_seconds();
					pace_cycle = avr->cycle;
					break;
				}
				if (wait <= 0 || g_stop_signal)
					break;
				if (service_io(wait) < 0) {
					reason = "I/O closed";
					break;
				}
			}
		}
	}

	/* last words from the firmware */
	if (g.out.len > 0) {
		for (int i = 0; i < 50 && g.out.len > 0; i++) {
			struct pollfd p = { .fd = g.out_fd, .events = POLLOUT };
			if (poll(&p, 1, 20) <= 0 || flush_output(0) < 0)
				break;
		}
	}

	const double wall = now_seconds() - wall_start;
	const avr_cycle_count_t cycles = avr->cycle - start_cycle;
	const double sim = (double)cycles / freq;
	logmsg("stopped: %s", reason);
	logmsg("simulated %.6f s (%" PRIu64 " cycles) in %.3f s wall (%.2fx real time)",
	       sim, (uint64_t)cycles, wall, wall > 0 ? sim / wall : 0.0);
	logmsg("AVR state %s, pc 0x%04" PRIx32 " (word 0x%04" PRIx32 ")", state_name(state),
	       (uint32_t)avr->pc, (uint32_t)avr->pc / 2);
	logmsg("UART0: %" PRIu64 " bytes out, %" PRIu64 " bytes in, %" PRIu64
	       " output bytes dropped (nobody reading), %zu input bytes not delivered, %" PRIu64
	       " XOFF", g.uart.bytes_out, g.uart.bytes_in, g.bytes_dropped_out, g.in.len,
	       g.uart.xoffs);
	if (state == cpu_Crashed)
		logmsg("CRASH: the simulated core crashed at pc 0x%04" PRIx32
		       " (word 0x%04" PRIx32 "); disassemble with avr-objdump -d %s",
		       (uint32_t)avr->pc, (uint32_t)avr->pc / 2, g.elf_path);

	if (g.vcd_open)
		avr_vcd_close(&g.vcd);
	avr_terminate(avr);
	if (g.pty_slave_fd >= 0)
		close(g.pty_slave_fd);
	return exit_code;
}
