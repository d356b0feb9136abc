/* Build-time configuration shared by the firmware modules.
 *
 * The generated headers (written by `bmg160-emu firmware build`) supply the I2C
 * address and the noise coefficients (bmg160_params.h) and the register map
 * (bmg160_registers.h); this file only holds fixed facts of the board. */
#ifndef BMG_CONFIG_H
#define BMG_CONFIG_H

#ifndef F_CPU
#define F_CPU 16000000UL /* Arduino Uno / Nano crystal */
#endif

#define BMG_STARTUP_MS 30         /* data sheet start-up time (spec 6.6) */
#define BMG_FAST_WAKE_MS 10       /* wake-up from fast power-up (spec 6.7) */
#define BMG_UART_BAUD 115200UL    /* enough for 200 Hz lines of ~30 bytes */

#endif
