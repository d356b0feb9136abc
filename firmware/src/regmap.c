/* Register semantics of the BMG160 as implemented on the ATmega328P.
 *
 * Reset values and write masks come from the generated header (the project's
 * register table); this file holds the behaviour: MSB shadowing (spec 6.2),
 * FIFO status and data (6.5), BW bit 7 (4.9), triggers (5.4), soft reset (6.6)
 * and power-mode write rules (6.7). A register with write mask 0 that is not
 * handled below reads its reset value and ignores writes. */
#include <avr/pgmspace.h>
#include <string.h>

#include "config.h"
#include "fifo.h"
#include "regmap.h"
#include "sampler.h"
#include "millis.h"
#include "bmg160_params.h"

#define REG_RATE_X_LSB 0x02
#define REG_RATE_Z_MSB 0x07
#define REG_INT_STATUS_1 0x0A
#define REG_FIFO_STATUS 0x0E
#define REG_RANGE 0x0F
#define REG_BW 0x10
#define REG_LPM1 0x11
#define REG_LPM2 0x12
#define REG_RATE_HBW 0x13
#define REG_BGW_SOFTRESET 0x14
#define REG_INT_EN_0 0x15
#define REG_FIFO_WM_EN 0x1E
#define REG_INT_RST_LATCH 0x21
#define REG_A_FOC 0x32
#define REG_TRIM_NVM_CTRL 0x33
#define REG_OFC1 0x36
#define REG_TRIM_GP0 0x3A
#define REG_BIST 0x3C
#define REG_FIFO_CONFIG_0 0x3D
#define REG_FIFO_CONFIG_1 0x3E

#define SOFTRESET_KEY 0xB6 /* spec 4.13 */

uint8_t bmg_regs[64];          /* the register file (peeked by the simulator) */
static uint8_t rate_now[6];    /* newest sample, LSB/MSB for X, Y, Z */
static uint8_t msb_shadow[3];
static uint8_t msb_locked;     /* bit per axis: LSB read, MSB latched */
static uint16_t bist_start_ms;
static uint8_t bist_triggered;
#define BIST_TIME_MS 5          /* self-test duration (spec 6.8, under the 10 ms BAPI waits) */

static void apply_power_mode(enum bmg_power_mode old_mode, uint8_t reg, uint8_t value);

uint8_t regmap_bw_code(void) { return bmg_regs[REG_BW] & 0x07; }

uint8_t regmap_range_code(void) { return bmg_regs[REG_RANGE] & 0x07; }

static int16_t sign_extend12(uint16_t v) { return (int16_t)(v << 4) >> 4; }

void regmap_offsets(int16_t offsets[3])
{
	uint8_t ofc1 = bmg_regs[REG_OFC1], gp0 = bmg_regs[REG_TRIM_GP0];
	offsets[0] = sign_extend12((uint16_t)(bmg_regs[0x37] << 4 | (ofc1 >> 6) << 2 | (gp0 >> 2 & 3)));
	offsets[1] = sign_extend12((uint16_t)(bmg_regs[0x38] << 4 | (ofc1 >> 3 & 7) << 1 | (gp0 >> 1 & 1)));
	offsets[2] = sign_extend12((uint16_t)(bmg_regs[0x39] << 4 | (ofc1 & 7) << 1 | (gp0 & 1)));
}

enum bmg_power_mode regmap_power_mode(void)
{
	/* Priority rule of spec 6.7. */
	uint8_t lpm1 = bmg_regs[REG_LPM1], lpm2 = bmg_regs[REG_LPM2];
	if (lpm1 & 0x20)
		return BMG_MODE_DEEP_SUSPEND;
	if (lpm1 & 0x80)
		return (lpm2 & 0x80) ? BMG_MODE_FAST_POWER_UP : BMG_MODE_SUSPEND;
	if (lpm2 & 0x40)
		return BMG_MODE_POWER_SAVE;
	return BMG_MODE_NORMAL;
}

static uint8_t mode_samples(enum bmg_power_mode mode)
{
	return mode == BMG_MODE_NORMAL || mode == BMG_MODE_POWER_SAVE;
}

void regmap_reset(void)
{
	memcpy_P(bmg_regs, bmg_reset_values, sizeof bmg_regs);
	memset(rate_now, 0, sizeof rate_now);
	msb_locked = 0;
	bist_triggered = 0;
	fifo_clear();
	fifo_clear_overrun();
	sampler_set_bw(regmap_bw_code());
	sampler_restart(BMG_STARTUP_MS);
}

void regmap_publish(const int16_t counts[3])
{
	for (uint8_t i = 0; i < 3; i++) {
		rate_now[2 * i] = (uint8_t)counts[i];
		rate_now[2 * i + 1] = (uint8_t)((uint16_t)counts[i] >> 8);
	}
	memcpy(&bmg_regs[REG_RATE_X_LSB], rate_now, 6);
	fifo_push(counts, bmg_regs[REG_FIFO_CONFIG_1] >> 6);
	sampler_mark_published();
}

static uint8_t int_status_1(void)
{
	uint8_t status = 0;
	uint8_t en = bmg_regs[REG_INT_EN_0];
	if ((en & 0x80) && sampler_data_pulse())
		status |= 0x80; /* data_int, a short non-latched pulse (spec 6.3) */
	if (en & 0x40) {
		uint8_t frames = fifo_frame_count();
		uint8_t level = (bmg_regs[REG_FIFO_WM_EN] & 0x80)
			? (bmg_regs[REG_FIFO_CONFIG_0] & 0x7F) : FIFO_CAPACITY;
		if (!level)
			level = 1; /* a watermark of 0 fires from one frame */
		if (frames >= level)
			status |= 0x10; /* fifo_int at watermark, or full (spec 6.5) */
	}
	return status;
}

uint8_t regmap_read(uint8_t reg)
{
	if (reg >= BMG_REG_COUNT)
		return 0x00; /* outside the user map (spec 2.4) */
	if (reg >= REG_RATE_X_LSB && reg <= REG_RATE_Z_MSB) {
		uint8_t axis = (uint8_t)((reg - REG_RATE_X_LSB) >> 1);
		uint8_t bit = (uint8_t)(1 << axis);
		uint8_t shadowing = !(bmg_regs[REG_RATE_HBW] & 0x40);
		if (!(reg & 1)) { /* LSB: latch the matching MSB */
			if (shadowing) {
				msb_shadow[axis] = rate_now[2 * axis + 1];
				msb_locked |= bit;
			}
			return rate_now[2 * axis];
		}
		if (msb_locked & bit) {
			msb_locked &= (uint8_t)~bit;
			if (shadowing)
				return msb_shadow[axis];
		}
		return rate_now[2 * axis + 1];
	}
	switch (reg) {
	case REG_INT_STATUS_1:
		return int_status_1();
	case REG_FIFO_STATUS:
		return (uint8_t)((fifo_overrun() << 7) | fifo_frame_count());
	case REG_BIST: {
		uint8_t value = sampler_valid() ? 0x10 : 0x00; /* rate_ok */
		if (bist_triggered && (uint16_t)(millis() - bist_start_ms) >= BIST_TIME_MS)
			value |= 0x02; /* bist_rdy, never bist_fail */
		return value;
	}
	case BMG_FIFO_DATA:
		return fifo_read_byte(bmg_regs[REG_FIFO_CONFIG_0], bmg_regs[REG_FIFO_CONFIG_1]);
	default:
		return bmg_regs[reg];
	}
}

static uint8_t write_allowed(uint8_t reg, enum bmg_power_mode mode)
{
	switch (mode) {
	case BMG_MODE_DEEP_SUSPEND:
		return reg == REG_LPM1 || reg == REG_BGW_SOFTRESET;
	case BMG_MODE_SUSPEND:
	case BMG_MODE_FAST_POWER_UP:
		return reg == REG_LPM1 || reg == REG_LPM2 || reg == REG_BGW_SOFTRESET;
	default:
		return 1;
	}
}

void regmap_write(uint8_t reg, uint8_t value)
{
	enum bmg_power_mode mode = regmap_power_mode();
	uint8_t mask, old;

	if (reg >= BMG_REG_COUNT || !write_allowed(reg, mode))
		return;
	if (reg == REG_BGW_SOFTRESET) {
		if (value == SOFTRESET_KEY)
			regmap_reset();
		return;
	}
	mask = pgm_read_byte(&bmg_write_masks[reg]);
	old = bmg_regs[reg];
	bmg_regs[reg] = (uint8_t)((bmg_regs[reg] & ~mask) | (value & mask));
	switch (reg) {
	case REG_BW:
		if ((old ^ bmg_regs[REG_BW]) & 0x07) {
			sampler_discard_backlog();
			sampler_set_bw(regmap_bw_code());
		}
		break;
	case REG_LPM1:
	case REG_LPM2:
		apply_power_mode(mode, reg, value);
		break;
	case REG_INT_RST_LATCH:
		if (value & 0x40) { /* offset_reset: offsets to 0 (spec 4.19, 6.9) */
			bmg_regs[REG_OFC1] = 0;
			bmg_regs[REG_OFC1 + 1] = 0;
			bmg_regs[REG_OFC1 + 2] = 0;
			bmg_regs[REG_OFC1 + 3] = 0;
			bmg_regs[REG_TRIM_GP0] &= 0xF0;
		}
		break;
	case REG_TRIM_NVM_CTRL:
		if (value & 0x08) /* nvm_load: the factory image, all zeros (spec 6.10) */
			memset(&bmg_regs[REG_OFC1], 0, 6);
		break;
	case REG_BIST:
		if (value & 0x01) {
			bist_start_ms = millis();
			bist_triggered = 1;
		}
		break;
	case REG_FIFO_CONFIG_0:
		sampler_discard_backlog();
		fifo_clear();
		break;
	case REG_FIFO_CONFIG_1:
		sampler_discard_backlog();
		fifo_clear();
		fifo_clear_overrun();
		break;
	default:
		break;
	}
}

static void apply_power_mode(enum bmg_power_mode old_mode, uint8_t reg, uint8_t value)
{
	enum bmg_power_mode mode = regmap_power_mode();
	if (mode == old_mode)
		return;
	if (old_mode == BMG_MODE_DEEP_SUSPEND) {
		/* Leaving deep suspend is a reset, then the LPM1 write is kept (spec 6.7). */
		regmap_reset();
		if (reg == REG_LPM1)
			bmg_regs[REG_LPM1] = value & pgm_read_byte(&bmg_write_masks[REG_LPM1]);
		if (!mode_samples(regmap_power_mode()))
			sampler_stop();
		return;
	}
	if (mode_samples(mode) == mode_samples(old_mode))
		return;
	if (mode_samples(mode))
		sampler_restart(old_mode == BMG_MODE_FAST_POWER_UP ? BMG_FAST_WAKE_MS : BMG_STARTUP_MS);
	else
		sampler_stop();
}
