/*
 * Copyright (c) 2026 The bmg160-emu contributors
 * SPDX-License-Identifier: MIT
 *
 * Emulators for Zephyr's I2C and SPI emulator buses whose chips live in
 * `bmg160-emu serve`: the BMG160 (bosch,bmg160), the BMI08x gyroscope
 * (bosch,bmi08x-gyro) and the BMI08x accelerometer's bus side
 * (bosch,bmi08x-accel, a register-file stand-in in the server). Each transfer
 * the driver makes goes whole to the server, at the simulated time; the
 * chip's INT pin reaches the GPIO the node's int-gpios names.
 *
 * The server's status values are Linux errno numbers (the protocol's); the
 * driver gets what a Zephyr controller gives: -EIO for a NACK.
 */

#include <errno.h>

#include <zephyr/device.h>
#include <zephyr/drivers/emul.h>
#include <zephyr/drivers/emul_sensor.h>
#include <zephyr/drivers/gpio.h>
#include <zephyr/drivers/i2c.h>
#include <zephyr/drivers/i2c_emul.h>
#include <zephyr/drivers/spi.h>
#include <zephyr/drivers/spi_emul.h>
#include <zephyr/sys/util.h>

#include "bmg160_emu_link.h"
#include "bmg160_emu_top.h"

#define LINUX_EREMOTEIO 121
#define LINUX_ENXIO 6
#define LINUX_ETIMEDOUT 110
#define LINUX_EINVAL 22
#define LINUX_ENODEV 19
#define LINUX_EBUSY 16
#define MAX_MESSAGES 42

struct gyro_emul_cfg {
	const char *name;
	uint16_t reg; /* I2C address or SPI chip select */
	bool on_spi;
	struct gpio_dt_spec int_gpio;
	uint8_t int_pin; /* which chip pin int-gpios is wired to: 1 or 2 */
};

struct gyro_emul_data {
	int chip;          /* index in the server's chip list */
	double rate_dps[3]; /* the true rate last set through the backend API */
};

static int zephyr_errno(int status)
{
	switch (-status) {
	case 0:
		return 0;
	case LINUX_EREMOTEIO:
	case LINUX_ENXIO:
		return -EIO; /* a NACK */
	case LINUX_ETIMEDOUT:
		return -ETIMEDOUT;
	case LINUX_EINVAL:
		return -EINVAL;
	case LINUX_ENODEV:
		return -ENODEV;
	case LINUX_EBUSY:
		return -EBUSY;
	default:
		return -EIO;
	}
}

static int __maybe_unused gyro_emul_transfer_i2c(const struct emul *target, struct i2c_msg *msgs,
				  int num_msgs, int addr)
{
	struct bmg_emu_i2c_msg out[MAX_MESSAGES];
	uint8_t zephyr_flags[MAX_MESSAGES];
	uint16_t flags[MAX_MESSAGES];
	int rc;

	ARG_UNUSED(target);
	if (num_msgs < 1 || num_msgs > MAX_MESSAGES) {
		return -EINVAL;
	}
	for (int i = 0; i < num_msgs; i++) {
		zephyr_flags[i] = msgs[i].flags;
	}
	bmg_emu_i2c_flags_from_zephyr(zephyr_flags, num_msgs, flags);
	for (int i = 0; i < num_msgs; i++) {
		out[i] = (struct bmg_emu_i2c_msg){
			.addr = (uint16_t)addr,
			.flags = flags[i],
			.len = msgs[i].len,
			.buf = msgs[i].buf,
		};
	}
	rc = bmg_emu_bottom_i2c(out, num_msgs);
	bmg_emu_top_after_transfer();
	return zephyr_errno(rc);
}

static int __maybe_unused gyro_emul_io_spi(const struct emul *target, const struct spi_config *config,
			    const struct spi_buf_set *tx_bufs, const struct spi_buf_set *rx_bufs)
{
	const struct gyro_emul_cfg *cfg = target->cfg;
	uint16_t mode;
	int rc;

	if (bmg_emu_spi_mode_from_zephyr(config->operation, &mode) != 0) {
		return -ENOTSUP;
	}
	rc = bmg_emu_bottom_spi((uint8_t)cfg->reg, mode,
				tx_bufs ? (const struct bmg_emu_buf *)tx_bufs->buffers : NULL,
				tx_bufs ? (int)tx_bufs->count : 0,
				rx_bufs ? (const struct bmg_emu_buf *)rx_bufs->buffers : NULL,
				rx_bufs ? (int)rx_bufs->count : 0);
	bmg_emu_top_after_transfer();
	return zephyr_errno(rc);
}

static struct i2c_emul_api gyro_emul_api_i2c __maybe_unused = {
	.transfer = gyro_emul_transfer_i2c,
};

static struct spi_emul_api gyro_emul_api_spi __maybe_unused = {
	.io = gyro_emul_io_spi,
};

/* Zephyr's emulated-sensor backend: a test sets the true rate (rad/s) and the
 * chip's noise, filter and counts do the rest (emul_sensor_backend_set_channel).
 */
#define RAD_TO_DEG 57.29577951308232
#define FULL_SCALE_RAD_S 34.906585 /* 2000 deg/s */

static int gyro_emul_set_channel(const struct emul *target, struct sensor_chan_spec ch,
				 const q31_t *value, int8_t shift)
{
	struct gyro_emul_data *data = target->data;
	double scale = (double)(1LL << (shift + 32)) / 4294967296.0 / 2147483648.0;
	int first;
	int count;

	switch (ch.chan_type) {
	case SENSOR_CHAN_GYRO_X:
	case SENSOR_CHAN_GYRO_Y:
	case SENSOR_CHAN_GYRO_Z:
		first = ch.chan_type - SENSOR_CHAN_GYRO_X;
		count = 1;
		break;
	case SENSOR_CHAN_GYRO_XYZ:
		first = 0;
		count = 3;
		break;
	default:
		return -ENOTSUP;
	}
	if (shift < -31 || shift > 31) {
		return -EINVAL;
	}
	for (int i = 0; i < count; i++) {
		data->rate_dps[first + i] = (double)value[i] * scale * RAD_TO_DEG;
	}
	return zephyr_errno(bmg_emu_bottom_set_rate((uint8_t)data->chip, data->rate_dps[0],
						    data->rate_dps[1], data->rate_dps[2]));
}

static int gyro_emul_get_sample_range(const struct emul *target, struct sensor_chan_spec ch,
				      q31_t *lower, q31_t *upper, q31_t *epsilon, int8_t *shift)
{
	ARG_UNUSED(target);
	if (ch.chan_type < SENSOR_CHAN_GYRO_X || ch.chan_type > SENSOR_CHAN_GYRO_XYZ) {
		return -ENOTSUP;
	}
	*shift = 6; /* 2^6 rad/s > the widest range, 2000 deg/s */
	*upper = (q31_t)(FULL_SCALE_RAD_S / 64.0 * 2147483647.0);
	*lower = -*upper;
	*epsilon = (q31_t)(FULL_SCALE_RAD_S / 32768.0 / 64.0 * 2147483647.0); /* one LSB */
	return 0;
}

static const struct emul_sensor_driver_api gyro_emul_backend_api = {
	.set_channel = gyro_emul_set_channel,
	.get_sample_range = gyro_emul_get_sample_range,
};

/* bmg160-emu,int-wiring nodes: a sensor's INT1 and INT2 wired where its own
 * binding cannot say (Zephyr's bmg160 binding has one int-gpios)
 */
struct int_wiring {
	const char *name;
	uint16_t reg;
	bool on_spi;
	struct gpio_dt_spec int1;
	struct gpio_dt_spec int2;
};

#define INT_WIRING(node_id)                                                                        \
	{                                                                                          \
		.name = DT_NODE_FULL_NAME(node_id),                                                \
		.reg = DT_REG_ADDR(DT_PHANDLE(node_id, sensor)),                                   \
		.on_spi = DT_ON_BUS(DT_PHANDLE(node_id, sensor), spi),                             \
		.int1 = GPIO_DT_SPEC_GET_OR(node_id, int1_gpios, {0}),                             \
		.int2 = GPIO_DT_SPEC_GET_OR(node_id, int2_gpios, {0}),                             \
	},

static const struct int_wiring int_wirings[] = {
	DT_FOREACH_STATUS_OKAY(bmg160_emu_int_wiring, INT_WIRING){0}};

static void wire_extra_pins(void)
{
	static bool done;

	if (done) {
		return;
	}
	done = true;
	for (size_t i = 0; int_wirings[i].name != NULL; i++) {
		const struct int_wiring *w = &int_wirings[i];
		int chip = w->on_spi ? bmg_emu_top_chip_spi(w->reg, w->name)
				     : bmg_emu_top_chip_i2c(w->reg, w->name);

		bmg_emu_top_wire(chip, 1, &w->int1, w->name);
		bmg_emu_top_wire(chip, 2, &w->int2, w->name);
	}
}

static int gyro_emul_init(const struct emul *target, const struct device *parent)
{
	const struct gyro_emul_cfg *cfg = target->cfg;
	struct gyro_emul_data *data = target->data;

	ARG_UNUSED(parent);
	bmg_emu_top_open();
	data->chip = cfg->on_spi ? bmg_emu_top_chip_spi(cfg->reg, cfg->name)
				 : bmg_emu_top_chip_i2c(cfg->reg, cfg->name);
	bmg_emu_top_wire(data->chip, cfg->int_pin, &cfg->int_gpio, cfg->name);
	wire_extra_pins();
	return 0;
}

/* int-gpios carries INT1 (bmg160) or the pin int3-4-map-io sends data ready
 * to (bmi08x-gyro: bit 0 INT3, bit 7 INT4)
 */
#define INT_PIN_FROM_MAP(map) (((map) & 0x01) || !((map) & 0x80) ? 1 : 2)

#define GYRO_EMUL(node_id, pin)                                                                    \
	static struct gyro_emul_data _CONCAT(gyro_emul_data_, DT_DEP_ORD(node_id));               \
	static const struct gyro_emul_cfg _CONCAT(gyro_emul_cfg_, DT_DEP_ORD(node_id)) = {         \
		.name = DT_NODE_FULL_NAME(node_id),                                                \
		.reg = DT_REG_ADDR(node_id),                                                       \
		.on_spi = DT_ON_BUS(node_id, spi),                                                 \
		.int_gpio = GPIO_DT_SPEC_GET_OR(node_id, int_gpios, {0}),                          \
		.int_pin = (pin),                                                                  \
	};                                                                                         \
	EMUL_DT_DEFINE(node_id, gyro_emul_init, &_CONCAT(gyro_emul_data_, DT_DEP_ORD(node_id)),    \
		       &_CONCAT(gyro_emul_cfg_, DT_DEP_ORD(node_id)),                              \
		       COND_CODE_1(DT_ON_BUS(node_id, spi), (&gyro_emul_api_spi),                  \
				   (&gyro_emul_api_i2c)),                                          \
		       &gyro_emul_backend_api);

#define BMG160_EMUL(node_id) GYRO_EMUL(node_id, 1)
#define BMI08X_GYRO_EMUL(node_id)                                                                  \
	GYRO_EMUL(node_id, INT_PIN_FROM_MAP(DT_PROP_OR(node_id, int3_4_map_io, 1)))
#define BMI08X_ACCEL_EMUL(node_id) GYRO_EMUL(node_id, 1)

DT_FOREACH_STATUS_OKAY(bosch_bmg160, BMG160_EMUL)
DT_FOREACH_STATUS_OKAY(bosch_bmi08x_gyro, BMI08X_GYRO_EMUL)
DT_FOREACH_STATUS_OKAY(bosch_bmi08x_accel, BMI08X_ACCEL_EMUL)
