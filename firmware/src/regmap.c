/* Register semantics of the BMG160 as implemented on the ATmega328P.
 *
 * Addresses, field masks, reset values and write masks come from the generated
 * bmg160_registers.h (the project's register table, bmg160_emu/device/registers.py);
 * this file holds the behaviour: MSB shadowing (spec 6.2),
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
#include "bmg160_registers.h"

/* Field value of a register byte, and the byte with a field set (generated masks). */
#define FIELD(value, reg_field) (((value) & reg_field##_MASK) >> reg_field##_SHIFT)

#define SOFTRESET_KEY 0xB6 /* spec 4.13 */

uint8_t bmg_regs[64];          /* the register file (peeked by the simulator) */
static uint8_t rate_now[6];    /* newest sample, LSB/MSB for X, Y, Z */
static uint8_t msb_shadow[3];
static uint8_t msb_locked;     /* bit per axis: LSB read, MSB latched */
static uint16_t bist_start_ms;
static uint8_t bist_triggered;
#define BIST_TIME_MS 5          /* self-test duration (spec 6.8, under the 10 ms BAPI waits) */

static void apply_power_mode(enum bmg_power_mode old_mode, uint8_t reg, uint8_t value);

/* Codes 8..15 behave as code & 7 (spec 4.9): the eight codes of table 5.3. */
uint8_t regmap_bw_code(void) { return FIELD(bmg_regs[BMG_REG_BW], BMG_BW_BW) & 7; }

uint8_t regmap_range_code(void) { return FIELD(bmg_regs[BMG_REG_RANGE], BMG_RANGE_RANGE); }

static int16_t sign_extend12(uint16_t v) { return (int16_t)(v << 4) >> 4; }

void regmap_offsets(int16_t offsets[3])
{
	/* offset = OFCn << 4 | OFC1 field << 1 or 2 | TRIM_GP0 bits (spec 4.24) */
	uint8_t ofc1 = bmg_regs[BMG_REG_OFC1], gp0 = bmg_regs[BMG_REG_TRIM_GP0];
	offsets[0] = sign_extend12((uint16_t)(bmg_regs[BMG_REG_OFC2] << 4
		| FIELD(ofc1, BMG_OFC1_OFFSET_X_3_2) << 2 | FIELD(gp0, BMG_TRIM_GP0_OFFSET_X_1_0)));
	offsets[1] = sign_extend12((uint16_t)(bmg_regs[BMG_REG_OFC3] << 4
		| FIELD(ofc1, BMG_OFC1_OFFSET_Y_3_1) << 1 | FIELD(gp0, BMG_TRIM_GP0_OFFSET_Y_0)));
	offsets[2] = sign_extend12((uint16_t)(bmg_regs[BMG_REG_OFC4] << 4
		| FIELD(ofc1, BMG_OFC1_OFFSET_Z_3_1) << 1 | FIELD(gp0, BMG_TRIM_GP0_OFFSET_Z_0)));
}

enum bmg_power_mode regmap_power_mode(void)
{
	/* Priority rule of spec 6.7. */
	uint8_t lpm1 = bmg_regs[BMG_REG_LPM1], lpm2 = bmg_regs[BMG_REG_LPM2];
	if (lpm1 & BMG_LPM1_DEEP_SUSPEND_MASK)
		return BMG_MODE_DEEP_SUSPEND;
	if (lpm1 & BMG_LPM1_SUSPEND_MASK)
		return (lpm2 & BMG_LPM2_FAST_POWER_UP_MASK) ? BMG_MODE_FAST_POWER_UP : BMG_MODE_SUSPEND;
	if (lpm2 & BMG_LPM2_POWER_SAVE_MODE_MASK)
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
	memcpy(&bmg_regs[BMG_REG_RATE_X_LSB], rate_now, 6);
	fifo_push(counts, FIELD(bmg_regs[BMG_REG_FIFO_CONFIG_1], BMG_FIFO_CONFIG_1_FIFO_MODE));
	sampler_mark_published();
}

static uint8_t int_status_1(void)
{
	uint8_t status = 0;
	uint8_t en = bmg_regs[BMG_REG_INT_EN_0];
	if ((en & BMG_INT_EN_0_DATA_EN_MASK) && sampler_data_pulse())
		status |= BMG_INT_STATUS_1_DATA_INT_MASK; /* a short non-latched pulse (spec 6.3) */
	if (en & BMG_INT_EN_0_FIFO_EN_MASK) {
		uint8_t frames = fifo_frame_count();
		uint8_t level = (bmg_regs[BMG_REG_FIFO_WM_EN] & BMG_FIFO_WM_EN_FIFO_WM_EN_MASK)
			? FIELD(bmg_regs[BMG_REG_FIFO_CONFIG_0],
				BMG_FIFO_CONFIG_0_FIFO_WATER_MARK_LEVEL_TRIGGER_RETAIN)
			: FIFO_CAPACITY;
		if (!level)
			level = 1; /* a watermark of 0 fires from one frame */
		if (frames >= level)
			status |= BMG_INT_STATUS_1_FIFO_INT_MASK; /* at watermark, or full (6.5) */
	}
	return status;
}

uint8_t regmap_read(uint8_t reg)
{
	if (reg >= BMG_REG_COUNT)
		return 0x00; /* outside the user map (spec 2.4) */
	if (reg >= BMG_REG_RATE_X_LSB && reg <= BMG_REG_RATE_Z_MSB) {
		uint8_t axis = (uint8_t)((reg - BMG_REG_RATE_X_LSB) >> 1);
		uint8_t bit = (uint8_t)(1 << axis);
		uint8_t shadowing = !(bmg_regs[BMG_REG_RATE_HBW] & BMG_RATE_HBW_SHADOW_DIS_MASK);
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
	case BMG_REG_INT_STATUS_1:
		return int_status_1();
	case BMG_REG_FIFO_STATUS:
		return (uint8_t)((fifo_overrun() << BMG_FIFO_STATUS_FIFO_OVERRUN_SHIFT)
			| fifo_frame_count());
	case BMG_REG_BIST: {
		uint8_t value = sampler_valid() ? BMG_BIST_RATE_OK_MASK : 0x00;
		if (bist_triggered && (uint16_t)(millis() - bist_start_ms) >= BIST_TIME_MS)
			value |= BMG_BIST_BIST_RDY_MASK; /* never bist_fail */
		return value;
	}
	case BMG_REG_FIFO_DATA:
		return fifo_read_byte(bmg_regs[BMG_REG_FIFO_CONFIG_0], bmg_regs[BMG_REG_FIFO_CONFIG_1]);
	default:
		return bmg_regs[reg];
	}
}

static uint8_t write_allowed(uint8_t reg, enum bmg_power_mode mode)
{
	switch (mode) {
	case BMG_MODE_DEEP_SUSPEND:
		return reg == BMG_REG_LPM1 || reg == BMG_REG_BGW_SOFTRESET;
	case BMG_MODE_SUSPEND:
	case BMG_MODE_FAST_POWER_UP:
		return reg == BMG_REG_LPM1 || reg == BMG_REG_LPM2 || reg == BMG_REG_BGW_SOFTRESET;
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
	if (reg == BMG_REG_BGW_SOFTRESET) {
		if (value == SOFTRESET_KEY)
			regmap_reset();
		return;
	}
	mask = pgm_read_byte(&bmg_write_masks[reg]);
	old = bmg_regs[reg];
	bmg_regs[reg] = (uint8_t)((bmg_regs[reg] & ~mask) | (value & mask));
	switch (reg) {
	case BMG_REG_BW:
		if (FIELD(old ^ bmg_regs[BMG_REG_BW], BMG_BW_BW) & 7) { /* the code as it behaves */
			sampler_discard_backlog();
			sampler_set_bw(regmap_bw_code());
		}
		break;
	case BMG_REG_LPM1:
	case BMG_REG_LPM2:
		apply_power_mode(mode, reg, value);
		break;
	case BMG_REG_INT_RST_LATCH:
		if (value & BMG_INT_RST_LATCH_OFFSET_RESET_MASK) { /* offsets to 0 (4.19, 6.9) */
			bmg_regs[BMG_REG_OFC1] = 0;
			bmg_regs[BMG_REG_OFC2] = 0;
			bmg_regs[BMG_REG_OFC3] = 0;
			bmg_regs[BMG_REG_OFC4] = 0;
			bmg_regs[BMG_REG_TRIM_GP0] &= (uint8_t)~(BMG_TRIM_GP0_OFFSET_X_1_0_MASK
				| BMG_TRIM_GP0_OFFSET_Y_0_MASK | BMG_TRIM_GP0_OFFSET_Z_0_MASK);
		}
		break;
	case BMG_REG_TRIM_NVM_CTRL:
		if (value & BMG_TRIM_NVM_CTRL_NVM_LOAD_MASK) /* the factory image, zeros (6.10) */
			memset(&bmg_regs[BMG_REG_OFC1], 0, BMG_REG_TRIM_GP1 - BMG_REG_OFC1 + 1);
		break;
	case BMG_REG_BIST:
		if (value & BMG_BIST_TRIG_BIST_MASK) {
			bist_start_ms = millis();
			bist_triggered = 1;
		}
		break;
	case BMG_REG_FIFO_CONFIG_0:
		sampler_discard_backlog();
		fifo_clear();
		break;
	case BMG_REG_FIFO_CONFIG_1:
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
		if (reg == BMG_REG_LPM1)
			bmg_regs[BMG_REG_LPM1] = value & pgm_read_byte(&bmg_write_masks[BMG_REG_LPM1]);
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
