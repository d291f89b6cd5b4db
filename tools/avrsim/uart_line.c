/*
 * uart_line.c: the serial line into an AVR's UART that both simavr harnesses share (see
 * uart_line.h for what it models and how a harness uses it).
 */
#include "uart_line.h"

/* Every byte the firmware writes to UDR. */
static void uart_line_output_hook(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	uart_line_t *l = param;
	l->bytes_out++;
	l->sent(l->user, (uint8_t)value);
}

/* XON: the UART's input FIFO is empty (raised again and again while it stays so). */
static void uart_line_xon_hook(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	(void)value;
	((uart_line_t *)param)->ready = 1;
}

/* XOFF: 1 when the FIFO is full or the receiver was turned off; 0 before an XON. */
static void uart_line_xoff_hook(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	uart_line_t *l = param;
	if (value) {
		l->ready = 0;
		l->xoffs++;
	}
}

/* Feeds one byte per byte-time of the line while the UART has room. */
static avr_cycle_count_t uart_line_feed_timer(avr_t *avr, avr_cycle_count_t when, void *param)
{
	(void)avr;
	uart_line_t *l = param;
	if (l->waiting(l->user) > 0 && l->ready) {
		uint8_t b = l->take(l->user);
		l->last_feed_cycle = when;
		l->bytes_in++;
		avr_raise_irq(l->in, b); /* may call uart_line_xoff_hook re-entrantly */
	}
	if (l->waiting(l->user) > 0)
		return when + l->cycles_per_byte;
	l->armed = 0;
	return 0;
}

/* Bytes are waiting: feed them from one byte-time after the last one went in (at once if that
 * has passed), unless the feed timer is already running. */
void uart_line_kick(uart_line_t *l)
{
	if (l->armed || l->waiting(l->user) == 0)
		return;
	avr_cycle_count_t due = l->last_feed_cycle + l->cycles_per_byte;
	avr_cycle_count_t delay = due > l->avr->cycle ? due - l->avr->cycle : 1;
	avr_cycle_timer_register(l->avr, delay, uart_line_feed_timer, l);
	l->armed = 1;
}

/* Connects the line to UART `name` ('0') of `avr`, at `baud`: no console echo of its output,
 * no usleep() when the firmware polls UCSRnA. Returns 0, or -1 when the MCU has no such UART. */
int uart_line_attach(uart_line_t *l, avr_t *avr, char name, uint32_t baud)
{
	l->avr = avr;
	uint32_t flags = 0;
	if (avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS(name), &flags) != 0)
		return -1;
	uint32_t ctl = AVR_IOCTL_UART_GETIRQ(name);
	l->in = avr_io_getirq(avr, ctl, UART_IRQ_INPUT);
	avr_irq_register_notify(avr_io_getirq(avr, ctl, UART_IRQ_OUTPUT), uart_line_output_hook, l);
	avr_irq_register_notify(avr_io_getirq(avr, ctl, UART_IRQ_OUT_XON), uart_line_xon_hook, l);
	avr_irq_register_notify(avr_io_getirq(avr, ctl, UART_IRQ_OUT_XOFF), uart_line_xoff_hook, l);
	l->cycles_per_byte = ((uint64_t)avr->frequency * UART_LINE_BITS_PER_BYTE + baud - 1) / baud;
	return 0;
}

/* After a reset: simavr cleared the cycle timers (the feed's among them) and possibly the cycle
 * counter, and the UART waits for its receiver to be enabled again (XON). */
void uart_line_after_reset(uart_line_t *l)
{
	l->armed = 0;
	l->last_feed_cycle = l->avr->cycle;
	l->ready = 0;
}
