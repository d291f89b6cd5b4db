/*
 * unocore_mpu.h: the MPU-6050 on the Uno's TWI bus (unocore_mpu.c).
 */
#ifndef ROVERNAV_UNOCORE_MPU_H
#define ROVERNAV_UNOCORE_MPU_H

#include <stdint.h>

#include "unocore.h"

/* Puts the chip at 7-bit address mpu_addr on the bus of u->avr, alive and just powered up, with
 * the TWI workarounds. Returns 0, or -1 when the MCU has no TWI. */
int mpu_attach(unocore *u, uint8_t mpu_addr);

/* After a reset: the bus is idle (nothing addressed, no SLA+W status awaited). */
void mpu_after_reset(unocore *u);

#endif /* ROVERNAV_UNOCORE_MPU_H */
