/*
 * unocore_mpu.c: the MPU-6050 on the Uno's TWI bus: a TWI slave at 0x68 (board.h kMpuAddress)
 * with a register file (auto-incrementing register pointer, WHO_AM_I 0x68, DEVICE_RESET, SLEEP,
 * FS_SEL) whose GYRO_ZOUT is the host's yaw rate (unocore_set_gyro).
 *
 * libsimavr 1.6 (Debian) and the TWI master: two bugs, worked round from here
 *   1. After SLA+W the master reports TWSR 0x28/0x30 (data byte sent, ACK/NACK) instead of
 *      0x18/0x20 (SLA+W sent, ACK/NACK): 1.6 uses the data-byte codes for the address byte of
 *      a write. The firmware's driver checks for 0x18 and would give up with a bus error. The
 *      harness listens to the TWI status IRQ, which simavr raises right after it has written
 *      TWSR and before it sets TWINT; when the status that follows an SLA+W is 0x28 or 0x30,
 *      it rewrites TWSR's status bits to 0x18 or 0x20. The firmware polls TWINT, so it only
 *      ever reads the corrected value.
 *   2. Writing 1 to TWINT does not clear it: 1.6's TWCR handler clears the TWI interrupt's
 *      pending state but leaves the TWINT bit as written (1). A driver that starts a bus step
 *      by writing TWINT=1 and then waits for TWINT to be set again would see it set at once
 *      and read a stale status. The harness registers a second write hook on TWCR, which
 *      simavr chains after the TWI module's own: when the value written has TWINT set, it
 *      clears the bit, as the hardware does. The TWI module sets it again when the bus step
 *      completes (its status timer raises the interrupt flag). The same hook would clear TWSTO
 *      if a library left it set after sending the STOP (the hardware clears it; the driver
 *      waits for that before the next START): Debian's 1.6 clears it itself, and
 *      twi_twsto_cleared stays 0.
 */
#include <string.h>

#include "avr_twi.h"
#include "sim_io.h"

#include "unocore_mpu.h"

enum { TWINT_BIT = 0x80, TWSTO_BIT = 0x10 };
enum {
	TW_START_ = 0x08, TW_MT_SLA_ACK_ = 0x18, TW_MT_SLA_NACK_ = 0x20,
	TW_MT_DATA_ACK_ = 0x28, TW_MT_DATA_NACK_ = 0x30,
};

enum {
	MPU_SMPLRT_DIV = 0x19, MPU_CONFIG = 0x1A, MPU_GYRO_CONFIG = 0x1B, MPU_ACCEL_CONFIG = 0x1C,
	MPU_SENSOR_FIRST = 0x3B, MPU_SENSOR_LAST = 0x48,
	MPU_PWR_MGMT_1 = 0x6B, MPU_WHO_AM_I = 0x75,
};

static void mpu_reset_regs(unocore *u)
{
	memset(u->regs, 0, sizeof u->regs);
	u->regs[MPU_PWR_MGMT_1] = 0x40; /* SLEEP after power-up and after DEVICE_RESET */
	u->regs[MPU_WHO_AM_I] = 0x68;
	u->reg_ptr = 0;
}

static int16_t clamp16(int64_t v)
{
	return (int16_t)(v > 32767 ? 32767 : v < -32768 ? -32768 : v);
}

/* The sensor registers, latched when a read transaction addresses the chip (the real chip
 * reads a burst from one sample). Asleep, the chip does not sample: zeros. */
static void mpu_latch(unocore *u)
{
	memset(u->latch, 0, sizeof u->latch);
	if (u->regs[MPU_PWR_MGMT_1] & 0x40)
		return;
	/* FS_SEL (GYRO_CONFIG bits 4:3): 131, 65.5, 32.8, 16.4 LSB per deg/s = 1310 / 2^fs per 10 */
	unsigned fs = (u->regs[MPU_GYRO_CONFIG] >> 3) & 3;
	int64_t num = (int64_t)u->gyro_chip_mdps * 131;
	int64_t den = 1000LL << fs;    /* counts = mdps * 131 / (1000 * 2^fs) */
	int64_t counts = (num >= 0 ? num + den / 2 : num - den / 2) / den;
	int16_t z = clamp16(counts);
	/* AFS_SEL (ACCEL_CONFIG bits 4:3): 16384 / 2^afs LSB per g; the rover stands level */
	int16_t one_g = (int16_t)(16384 >> ((u->regs[MPU_ACCEL_CONFIG] >> 3) & 3));
	u->latch[0x3F - MPU_SENSOR_FIRST] = (uint8_t)((uint16_t)one_g >> 8);   /* ACCEL_ZOUT */
	u->latch[0x40 - MPU_SENSOR_FIRST] = (uint8_t)one_g;
	int16_t temp = (int16_t)((25.0 - 36.53) * 340.0);                     /* 25 C */
	u->latch[0x41 - MPU_SENSOR_FIRST] = (uint8_t)((uint16_t)temp >> 8);
	u->latch[0x42 - MPU_SENSOR_FIRST] = (uint8_t)temp;
	u->latch[0x47 - MPU_SENSOR_FIRST] = (uint8_t)((uint16_t)z >> 8);       /* GYRO_ZOUT */
	u->latch[0x48 - MPU_SENSOR_FIRST] = (uint8_t)z;
}

static uint8_t mpu_read(unocore *u)
{
	uint8_t reg = u->reg_ptr & (MPU_REGS - 1);
	u->reg_ptr = (uint8_t)((reg + 1) & (MPU_REGS - 1));
	if (reg == MPU_WHO_AM_I)
		u->st.twi_whoami_reads++;
	if (reg == 0x47)
		u->st.twi_gyro_reads++;
	if (reg >= MPU_SENSOR_FIRST && reg <= MPU_SENSOR_LAST)
		return u->latch[reg - MPU_SENSOR_FIRST];
	return u->regs[reg];
}

static void mpu_write(unocore *u, uint8_t value)
{
	uint8_t reg = u->reg_ptr & (MPU_REGS - 1);
	u->reg_ptr = (uint8_t)((reg + 1) & (MPU_REGS - 1));
	if (reg == MPU_WHO_AM_I || (reg >= MPU_SENSOR_FIRST && reg <= MPU_SENSOR_LAST))
		return; /* read-only */
	if (reg == MPU_PWR_MGMT_1 && (value & 0x80)) {
		mpu_reset_regs(u); /* DEVICE_RESET: every register to its default, the bit clears */
		return;
	}
	u->regs[reg] = value;
}

static void twi_answer(unocore *u, uint8_t msg, uint8_t addr, uint8_t data)
{
	avr_raise_irq(u->twi_in, avr_twi_irq_msg(msg, addr, data));
}

/* Everything the TWI master puts on the bus. simavr expects a slave to answer at once, by
 * raising the TWI input IRQ: an ACK for an address or a written byte, the byte for a read. */
static void twi_output_hook(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	unocore *u = param;
	avr_twi_msg_irq_t v;
	v.u.v = value;
	uint8_t msg = v.u.twi.msg, addr = v.u.twi.addr, data = v.u.twi.data;
	u->dirty = 1;

	if (msg & TWI_COND_STOP) {
		u->selected = 0;
		u->addr_w_status_pending = 0;
	}
	if (msg & TWI_COND_START) {
		/* START with an address byte: SLA+R or SLA+W */
		u->selected = 0;
		int is_write = (addr & 1) == 0;
		u->addr_w_status_pending = is_write;
		if ((addr >> 1) == u->mpu_addr && u->gyro_alive) {
			u->selected = 1;
			u->st.twi_addressed++;
			if (is_write)
				u->first_write = 1;
			else
				mpu_latch(u);
			twi_answer(u, TWI_COND_ACK, addr, 1);
		} else {
			u->st.twi_nacked++; /* nobody answers: the master sees a NACK */
		}
		return;
	}
	if (!u->selected)
		return;
	if (msg & TWI_COND_WRITE) {
		u->st.twi_bytes_written++;
		if (u->first_write) {
			u->reg_ptr = data & (MPU_REGS - 1);
			u->first_write = 0;
		} else {
			mpu_write(u, data);
		}
		twi_answer(u, TWI_COND_ACK, addr, 1);
	} else if (msg & TWI_COND_READ) {
		u->st.twi_bytes_read++;
		twi_answer(u, TWI_COND_READ, addr, mpu_read(u));
	}
}

/* Workaround 1 (see the top of this file): the status that answers an SLA+W. */
static void twi_status_hook(avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	unocore *u = param;
	u->dirty = 1;
	if (value == TW_START_)
		return; /* the START's own status comes before the address */
	if (u->addr_w_status_pending) {
		u->addr_w_status_pending = 0;
		uint8_t fixed = value == TW_MT_DATA_ACK_ ? TW_MT_SLA_ACK_
		              : value == TW_MT_DATA_NACK_ ? TW_MT_SLA_NACK_ : 0;
		if (fixed) {
			u->avr->data[A_TWSR] = (uint8_t)((u->avr->data[A_TWSR] & 0x07) | fixed);
			u->st.twi_status_fixed++;
		}
	}
}

/* Workaround 2 (see the top of this file): chained after the TWI module's TWCR write. */
static void twcr_write_hook(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
	unocore *u = param;
	u->dirty = 1;
	if ((v & TWINT_BIT) && (avr->data[addr] & TWINT_BIT)) {
		avr->data[addr] &= (uint8_t)~TWINT_BIT;
		u->st.twi_twint_cleared++;
	}
	if ((v & TWSTO_BIT) && (avr->data[addr] & TWSTO_BIT)) {
		avr->data[addr] &= (uint8_t)~TWSTO_BIT;
		u->st.twi_twsto_cleared++;
	}
}

/* ------------------------------------------------------------------------------ wiring */

int mpu_attach(unocore *u, uint8_t mpu_addr)
{
	avr_t *avr = u->avr;
	u->twi_in = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_INPUT);
	avr_irq_t *twi_out = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_OUTPUT);
	avr_irq_t *twi_status = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_STATUS);
	if (!u->twi_in || !twi_out || !twi_status)
		return -1;
	avr_irq_register_notify(twi_out, twi_output_hook, u);
	avr_irq_register_notify(twi_status, twi_status_hook, u);
	avr_register_io_write(avr, A_TWCR, twcr_write_hook, u);
	u->mpu_addr = mpu_addr;
	u->gyro_alive = 1;
	mpu_reset_regs(u);
	return 0;
}

void mpu_after_reset(unocore *u)
{
	u->selected = 0;
	u->addr_w_status_pending = 0;
}
