/*
 * Copyright (c) 2026 The bmg160-emu contributors
 * SPDX-License-Identifier: MIT
 *
 * What the emulators ask of the module's Zephyr side.
 */

#ifndef BMG160_EMU_TOP_H_
#define BMG160_EMU_TOP_H_

#include <stdint.h>
#include <zephyr/drivers/gpio.h>

/* Open the link to the server once (the first emulator's init does). */
int bmg_emu_top_open(void);

/* The server's chip at an I2C address or on a SPI chip select (exits with one
 * line naming `what` when the server has none).
 */
int bmg_emu_top_chip_i2c(uint16_t address, const char *what);
int bmg_emu_top_chip_spi(uint16_t cs, const char *what);

/* INT pin `int_pin` (1: INT1/INT3, 2: INT2/INT4) of `chip` drives `spec`. */
void bmg_emu_top_wire(int chip, int int_pin, const struct gpio_dt_spec *spec, const char *what);

/* After a transfer: the lines' levels into the GPIO inputs. */
void bmg_emu_top_after_transfer(void);

#endif /* BMG160_EMU_TOP_H_ */
