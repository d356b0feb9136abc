/*
 * Copyright (c) 2026 The bmg160-emu contributors
 * SPDX-License-Identifier: MIT
 *
 * A ztest suite on a gyroscope served by bmg160-emu: Zephyr's own driver, the
 * chip's noise and filter. The test sets the true rate through Zephyr's
 * emulated-sensor backend API and checks what the driver reads.
 */

#include <math.h>

#include <zephyr/device.h>
#include <zephyr/drivers/emul.h>
#include <zephyr/drivers/emul_sensor.h>
#include <zephyr/drivers/sensor.h>
#include <zephyr/kernel.h>
#include <zephyr/ztest.h>

#if DT_HAS_COMPAT_STATUS_OKAY(bosch_bmg160)
#define GYRO_NODE DT_COMPAT_GET_ANY_STATUS_OKAY(bosch_bmg160)
#else
#define GYRO_NODE DT_COMPAT_GET_ANY_STATUS_OKAY(bosch_bmi08x_gyro)
#endif

static const struct device *const gyro = DEVICE_DT_GET(GYRO_NODE);

static double mean_rad_s(enum sensor_channel axis, int samples)
{
	double sum = 0.0;

	for (int i = 0; i < samples; i++) {
		struct sensor_value v;

		zassert_ok(sensor_sample_fetch(gyro));
		zassert_ok(sensor_channel_get(gyro, axis, &v));
		sum += sensor_value_to_double(&v);
		k_msleep(10); /* one output period at 100 Hz */
	}
	return sum / samples;
}

ZTEST(served_gyro, test_the_driver_finds_the_chip)
{
	zassert_true(device_is_ready(gyro), "%s not ready", gyro->name);
}

ZTEST(served_gyro, test_a_rate_set_through_the_emulator_is_what_the_driver_reads)
{
	const struct emul *emul = EMUL_DT_GET(GYRO_NODE);
	q31_t half = INT32_MAX / 2; /* 0.5 * 2^1: 1 rad/s */
	struct sensor_chan_spec x = {.chan_type = SENSOR_CHAN_GYRO_X, .chan_idx = 0};

	zassert_ok(emul_sensor_backend_set_channel(emul, x, &half, 1));
	k_msleep(300); /* past the output filter's settling (12 Hz at 100 Hz ODR) */
	/* 50 samples of ~0.1 deg/s noise: the mean is within 0.05 deg/s (0.001 rad/s)
	 * of the rate and its bias; 0.02 rad/s is far outside what they can do
	 */
	zassert_within(mean_rad_s(SENSOR_CHAN_GYRO_X, 50), 1.0, 0.02);
}

ZTEST(served_gyro, test_at_rest_the_driver_reads_noise_around_zero)
{
	const struct emul *emul = EMUL_DT_GET(GYRO_NODE);
	q31_t zero = 0;
	struct sensor_chan_spec z = {.chan_type = SENSOR_CHAN_GYRO_Z, .chan_idx = 0};

	zassert_ok(emul_sensor_backend_set_channel(emul, z, &zero, 0));
	k_msleep(300);
	zassert_within(mean_rad_s(SENSOR_CHAN_GYRO_Z, 50), 0.0, 0.02);
}

ZTEST_SUITE(served_gyro, NULL, NULL, NULL, NULL, NULL);
