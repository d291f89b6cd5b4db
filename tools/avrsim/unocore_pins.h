/*
 * unocore_pins.h: what the harness wires to the Uno's pins and the simavr 1.6 workarounds for
 * its ports, external interrupts and timers (unocore_pins.c).
 */
#ifndef ROVERNAV_UNOCORE_PINS_H
#define ROVERNAV_UNOCORE_PINS_H

#include <stdint.h>

#include "unocore.h"

/* Once the firmware is loaded: the EIMSK hook and Timer modes (workarounds 3, 4), the HC-SR04's
 * TRIG and ECHO, the step probe on PB0 and the descriptor in GPIOR0. */
void pins_attach(unocore *u);

/* After a reset, in unocore.c's after_reset order: the echo goes low; a step the reset cut
 * short ends at cycle_before; INT0/INT1 polling off again (3); the pin IRQs take PINx's
 * values (5). */
void sonar_after_reset(unocore *u);
void probe_after_reset(unocore *u, uint64_t cycle_before);
void extint_after_reset(unocore *u);
void pin_irqs_after_reset(unocore *u);

/* Port 'B'..'D' bit held to GND (held != 0) or let go (see unocore_hold_pin_low). Returns 0, or
 * -1 for an unknown port or bit. */
int pins_hold_low(unocore *u, char port, uint8_t bit, int held);

#endif /* ROVERNAV_UNOCORE_PINS_H */
