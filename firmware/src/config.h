/* Build-time configuration shared by the firmware modules.
 *
 * The generated parameter header (bmg160_params.h, written by
 * `bmg160-emu firmware build`) supplies the I2C address, the register table and
 * the noise coefficients; this file only holds fixed facts of the board. */
#ifndef BMG_CONFIG_H
#define BMG_CONFIG_H

#ifndef F_CPU
#define F_CPU 16000000UL /* Arduino Uno / Nano crystal */
#endif

#define BMG_REG_COUNT 64          /* user map 0x00..0x3F (spec section 3) */
#define BMG_FIFO_DATA 0x3F        /* pointer stays here (spec 2.4) */
#define BMG_STARTUP_MS 30         /* data sheet start-up time (spec 6.6) */
#define BMG_FAST_WAKE_MS 10       /* wake-up from fast power-up (spec 6.7) */
#define BMG_UART_BAUD 115200UL    /* enough for 200 Hz lines of ~30 bytes */

#endif
