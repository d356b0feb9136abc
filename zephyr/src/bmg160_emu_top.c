/*
 * Copyright (c) 2026 The bmg160-emu contributors
 * SPDX-License-Identifier: MIT
 *
 * The module's Zephyr side (the "top"): opens the link through the host half
 * once, takes the module's interrupt when the server's line levels change and
 * moves the emulated GPIO inputs the chips' INT pins are wired to.
 */

#include <errno.h>
#include <string.h>

#include <zephyr/drivers/gpio.h>
#include <zephyr/drivers/gpio/gpio_emul.h>
#include <zephyr/drivers/i2c.h>
#include <zephyr/drivers/spi.h>
#include <zephyr/irq.h>
#include <zephyr/kernel.h>
#include <zephyr/logging/log.h>
#include <zephyr/sys/util.h>

#include <cmdline.h>
#include <posix_native_task.h>

#include "bmg160_emu_link.h"
#include "bmg160_emu_top.h"

LOG_MODULE_REGISTER(bmg160_emu, CONFIG_BMG160_EMU_LOG_LEVEL);

/* the translation in the host half uses Zephyr's values, repeated there */
BUILD_ASSERT(I2C_MSG_READ == BMG_EMU_ZEPHYR_I2C_MSG_READ);
BUILD_ASSERT(I2C_MSG_STOP == BMG_EMU_ZEPHYR_I2C_MSG_STOP);
BUILD_ASSERT(I2C_MSG_RESTART == BMG_EMU_ZEPHYR_I2C_MSG_RESTART);
BUILD_ASSERT(I2C_MSG_ADDR_10_BITS == BMG_EMU_ZEPHYR_I2C_MSG_ADDR_10_BITS);
BUILD_ASSERT(SPI_MODE_CPOL == BMG_EMU_ZEPHYR_SPI_MODE_CPOL);
BUILD_ASSERT(SPI_MODE_CPHA == BMG_EMU_ZEPHYR_SPI_MODE_CPHA);
BUILD_ASSERT(SPI_MODE_LOOP == BMG_EMU_ZEPHYR_SPI_MODE_LOOP);
BUILD_ASSERT(SPI_TRANSFER_LSB == BMG_EMU_ZEPHYR_SPI_TRANSFER_LSB);
BUILD_ASSERT(SPI_WORD_SET(8) == 8u << BMG_EMU_ZEPHYR_SPI_WORD_SIZE_SHIFT);
BUILD_ASSERT(SPI_HALF_DUPLEX == BMG_EMU_ZEPHYR_SPI_HALF_DUPLEX);
BUILD_ASSERT(SPI_HOLD_ON_CS == BMG_EMU_ZEPHYR_SPI_HOLD_ON_CS);
BUILD_ASSERT(SPI_CS_ACTIVE_HIGH == BMG_EMU_ZEPHYR_SPI_CS_ACTIVE_HIGH);
BUILD_ASSERT(sizeof(struct spi_buf) == sizeof(struct bmg_emu_buf));
BUILD_ASSERT(offsetof(struct spi_buf, len) == offsetof(struct bmg_emu_buf, len));

struct wire {
	const struct device *port;
	gpio_pin_t pin;
	uint8_t line; /* bit of the server's levels: 2 * chip + (INT pin - 1) */
	int8_t applied; /* the level last set on the input, -1 before it took one */
	bool refused; /* the pin was not an input when last set (told once) */
	const char *what;
};

static struct wire wires[CONFIG_BMG160_EMU_MAX_WIRES];
static int wire_count;
static const char *socket_path; /* --bmg160-emu=PATH */
static bool opened;

static void apply_levels(void)
{
	uint64_t levels = bmg_emu_bottom_levels();

	for (int i = 0; i < wire_count; i++) {
		struct wire *w = &wires[i];
		int level = (int)(levels >> w->line & 1u);
		gpio_flags_t flags = 0;

		if (w->applied == level) {
			continue;
		}
		(void)gpio_emul_flags_get(w->port, w->pin, &flags);
		if (!(flags & GPIO_INPUT)) {
			/* gpio_emul takes input levels on input pins only: a driver that
			 * configures its interrupt pin without GPIO_INPUT never sees it
			 */
			if (flags != 0 && !w->refused) {
				w->refused = true;
				LOG_WRN("%s: %s pin %u is configured without GPIO_INPUT (flags "
					"0x%x): its INT level is not delivered", w->what,
					w->port->name, w->pin, flags);
			}
			continue;
		}
		if (gpio_emul_input_set(w->port, w->pin, level) == 0) {
			w->applied = (int8_t)level;
		}
	}
}

void bmg_emu_top_after_transfer(void)
{
	apply_levels();
}

static void line_isr(const void *arg)
{
	ARG_UNUSED(arg);
	apply_levels();
}

int bmg_emu_top_open(void)
{
	if (opened) {
		return 0;
	}
	opened = true;
	IRQ_CONNECT(CONFIG_BMG160_EMU_IRQ, CONFIG_BMG160_EMU_IRQ_PRIORITY, line_isr, NULL, 0);
	irq_enable(CONFIG_BMG160_EMU_IRQ);
	return bmg_emu_bottom_open(socket_path, CONFIG_BMG160_EMU_SOCKET, CONFIG_BMG160_EMU_IRQ);
}

int bmg_emu_top_chip_i2c(uint16_t address, const char *what)
{
	int chip = bmg_emu_link_find_i2c(bmg_emu_bottom_link(), (uint8_t)address);

	if (chip < 0) {
		posix_print_error_and_exit("bmg160-emu: %s: the server has no chip at I2C address "
					   "0x%02x (serve --address / --device)\n", what, address);
	}
	return chip;
}

int bmg_emu_top_chip_spi(uint16_t cs, const char *what)
{
	int chip = bmg_emu_link_find_spi(bmg_emu_bottom_link(), (uint8_t)cs);

	if (chip < 0) {
		posix_print_error_and_exit("bmg160-emu: %s: the server has no chip on SPI chip "
					   "select %u (chip select i is its i-th device)\n", what, cs);
	}
	return chip;
}

void bmg_emu_top_wire(int chip, int int_pin, const struct gpio_dt_spec *spec, const char *what)
{
	const struct bmg_emu_link *link = bmg_emu_bottom_link();

	if (spec->port == NULL || chip < 0 || link->chips[chip].pins < int_pin) {
		return;
	}
	if (wire_count == ARRAY_SIZE(wires)) {
		posix_print_error_and_exit("bmg160-emu: more than %d wired INT pins "
					   "(CONFIG_BMG160_EMU_MAX_WIRES)\n", wire_count);
	}
	wires[wire_count++] = (struct wire){
		.port = spec->port,
		.pin = spec->pin,
		.line = (uint8_t)(2 * chip + int_pin - 1),
		.applied = -1,
		.what = what,
	};
	LOG_DBG("%s: INT%d -> %s pin %u", what, int_pin, spec->port->name, spec->pin);
}

static void add_options(void)
{
	static struct args_struct_t options[] = {
		{
			.option = "bmg160-emu",
			.name = "path",
			.type = 's',
			.dest = (void *)&socket_path,
			.descript = "UNIX socket of `bmg160-emu serve` (default: "
				    "$BMG160_EMU_SOCKET, then CONFIG_BMG160_EMU_SOCKET)",
		},
		ARG_TABLE_ENDMARKER,
	};

	native_add_command_line_opts(options);
}

NATIVE_TASK(add_options, PRE_BOOT_1, 20);
