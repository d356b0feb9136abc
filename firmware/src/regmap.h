/* The BMG160 register file as a bus slave sees it: reads with side effects
 * (MSB shadowing, FIFO), writes with masks, triggers and power-mode rules. */
#ifndef BMG_REGMAP_H
#define BMG_REGMAP_H
#include <stdint.h>

enum bmg_power_mode {
	BMG_MODE_NORMAL,
	BMG_MODE_DEEP_SUSPEND,
	BMG_MODE_SUSPEND,
	BMG_MODE_FAST_POWER_UP,
	BMG_MODE_POWER_SAVE,
};

extern uint8_t bmg_regs[64];

void regmap_reset(void);
uint8_t regmap_read(uint8_t reg);
void regmap_write(uint8_t reg, uint8_t value);
uint8_t regmap_bw_code(void);
uint8_t regmap_range_code(void);
/* The 12-bit offset of each axis (spec 4.24), in LSB of the +-2000 deg/s range. */
void regmap_offsets(int16_t offsets[3]);
enum bmg_power_mode regmap_power_mode(void);
/* Put one new sample (counts, X Y Z) into the rate registers and the FIFO. */
void regmap_publish(const int16_t counts[3]);

#endif
