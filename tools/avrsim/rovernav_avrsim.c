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
 *   the simulated UART (uart_line.c, the line model unocore.c uses too). When the input ring is
 *   full the bridge stops reading its input, and the kernel's pty/pipe buffer holds the rest.
 *
 *   Bytes the AVR sends go out as they are written to UDR0 (simavr already paces them at the
 *   configured baud rate). With --pty, if nobody reads the pty and the output ring fills up,
 *   further bytes are dropped and counted, as on a serial line nobody listens to. With --stdio,
 *   the simulation waits for the reader instead.
 *
 * The outside end (the pty or stdin/stdout, the rings, their service between slices) is in
 * avrsim_io.c.
 *
 * Exit status: 0 after a clean stop (--seconds reached, SIGINT/SIGTERM/SIGHUP, the AVR went to
 * sleep with interrupts off, stdout closed); 1 if the simulated core crashed; 2 on a usage or
 * load error.
 */
#define _GNU_SOURCE

#include <errno.h>
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
#include <time.h>
#include <unistd.h>

#include "avr_ioport.h"
#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_irq.h"
#include "sim_vcd_file.h"

#include "avrsim_io.h"
#include "uart_line.h"

#define DEFAULT_MCU "atmega328p"
#define DEFAULT_FREQ_HZ 16000000u
#define DEFAULT_BAUD 57600u
#define UART_NAME '0'
#define SLICE_PER_SECOND 1000u       /* simulate in 1 ms slices */
#define MAX_LAG_SECONDS 0.1          /* further behind than this: stop catching up */

/* ------------------------------------------------------------------------------ state */

static volatile sig_atomic_t g_stop_signal = 0;

static struct {
	/* options (and --pty/--stdio, -v: io.mode, io.verbose) */
	double speed;
	double seconds;          /* <= 0: no limit */
	const char *vcd_path;
	const char *elf_path;
	const char *mcu_default;
	uint32_t freq_default;
	uint32_t baud;

	/* simulation */
	avr_t *avr;
	uart_line_t uart;        /* UART0 (uart_line.c): input paced at the line's rate */
	avr_vcd_t vcd;
	int vcd_open;

	/* the outside world (avrsim_io.c) */
	bridge_io_t io;
} g = {
	.speed = 1.0,
	.seconds = 0.0,
	.mcu_default = DEFAULT_MCU,
	.freq_default = DEFAULT_FREQ_HZ,
	.baud = DEFAULT_BAUD,
	.io = {
		.mode = MODE_PTY,
		.uart = &g.uart,
		.stop = &g_stop_signal,
		.in_fd = -1,
		.out_fd = -1,
		.pty_slave_fd = -1,
	},
};

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
	g.avr->log = g.io.verbose ? LOG_TRACE : LOG_WARNING;
	avr_load_firmware(g.avr, &fw);
	g.avr->sleep = no_sleep;

	/* no console echo of UART output, no usleep() when the firmware polls UCSR0A */
	g.uart = (uart_line_t){.user = &g.io, .waiting = io_uart_waiting, .take = io_uart_take, .sent = io_uart_sent};
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
		case 'p': g.io.mode = MODE_PTY; break;
		case 's': g.io.mode = MODE_STDIO; break;
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
		case 'v': g.io.verbose = 1; break;
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
	if ((g.io.mode == MODE_PTY ? io_open_pty(&g.io) : io_open_stdio(&g.io)) != 0)
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
		if (io_service(&g.io, 0) < 0 && !reason)
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
				if (io_service(&g.io, wait) < 0) {
					reason = "I/O closed";
					break;
				}
			}
		}
	}

	/* last words from the firmware */
	if (g.io.out.len > 0) {
		for (int i = 0; i < 50 && g.io.out.len > 0; i++) {
			struct pollfd p = { .fd = g.io.out_fd, .events = POLLOUT };
			if (poll(&p, 1, 20) <= 0 || io_flush_output(&g.io, 0) < 0)
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
	       " XOFF", g.uart.bytes_out, g.uart.bytes_in, g.io.bytes_dropped_out, g.io.in.len,
	       g.uart.xoffs);
	if (state == cpu_Crashed)
		logmsg("CRASH: the simulated core crashed at pc 0x%04" PRIx32
		       " (word 0x%04" PRIx32 "); disassemble with avr-objdump -d %s",
		       (uint32_t)avr->pc, (uint32_t)avr->pc / 2, g.elf_path);

	if (g.vcd_open)
		avr_vcd_close(&g.vcd);
	avr_terminate(avr);
	if (g.io.pty_slave_fd >= 0)
		close(g.io.pty_slave_fd);
	return exit_code;
}

