/*
 * Copyright (c) 2026 The bmg160-emu contributors
 * SPDX-License-Identifier: MIT
 *
 * gyro_stats: read a gyroscope through Zephyr's own driver and print every
 * sample, so that a test can take the means, the noise and the counts of what
 * the driver saw (docs/zephyr.md). Polls once per output period by default;
 * with CONFIG_GYRO_STATS_TRIGGER it counts the driver's data-ready callbacks.
 *
 * Output: "GYRO-STATS device NAME", one "S i x1 x2 y1 y2 z1 z2" line per
 * sample (sensor_value pairs, rad/s), then "GYRO-STATS done n".
 */

#include <stdio.h>

#include <zephyr/device.h>
#include <zephyr/drivers/sensor.h>
#include <zephyr/kernel.h>

#if DT_HAS_COMPAT_STATUS_OKAY(bosch_bmg160)
#define GYRO_NODE DT_COMPAT_GET_ANY_STATUS_OKAY(bosch_bmg160)
#else
#define GYRO_NODE DT_COMPAT_GET_ANY_STATUS_OKAY(bosch_bmi08x_gyro)
#endif

#define STARTUP_MS 100 /* past the chip's 30 ms start-up after the driver's reset */

static int print_sample(const struct device *gyro, int index)
{
	struct sensor_value v[3];
	int rc = sensor_sample_fetch(gyro);

	if (rc == 0) {
		rc = sensor_channel_get(gyro, SENSOR_CHAN_GYRO_XYZ, v);
	}
	if (rc != 0) {
		printf("GYRO-STATS error %d at sample %d\n", rc, index);
		return rc;
	}
	printf("S %d %d %d %d %d %d %d\n", index, v[0].val1, v[0].val2, v[1].val1, v[1].val2,
	       v[2].val1, v[2].val2);
	return 0;
}

#ifdef CONFIG_GYRO_STATS_TRIGGER
static K_SEM_DEFINE(data_ready, 0, K_SEM_MAX_LIMIT);
static int callbacks;

static void on_data_ready(const struct device *gyro, const struct sensor_trigger *trigger)
{
	ARG_UNUSED(trigger);
	if (callbacks < CONFIG_GYRO_STATS_SAMPLES) {
		print_sample(gyro, callbacks);
	}
	callbacks++;
	k_sem_give(&data_ready);
}
#endif

int main(void)
{
	const struct device *gyro = DEVICE_DT_GET(GYRO_NODE);
	struct sensor_value odr = {.val1 = CONFIG_GYRO_STATS_ODR_HZ};
	int rc;

	if (!device_is_ready(gyro)) {
		printf("GYRO-STATS not ready %s\n", gyro->name);
		return 0;
	}
	printf("GYRO-STATS device %s\n", gyro->name);
	rc = sensor_attr_set(gyro, SENSOR_CHAN_GYRO_XYZ, SENSOR_ATTR_SAMPLING_FREQUENCY, &odr);
	printf("GYRO-STATS odr %d Hz: %d\n", CONFIG_GYRO_STATS_ODR_HZ, rc);
	k_msleep(STARTUP_MS);

#ifdef CONFIG_GYRO_STATS_TRIGGER
	struct sensor_trigger trigger = {.type = SENSOR_TRIG_DATA_READY,
					 .chan = SENSOR_CHAN_GYRO_XYZ};
	int64_t until = k_uptime_get() + 1000LL * CONFIG_GYRO_STATS_SAMPLES /
					     CONFIG_GYRO_STATS_ODR_HZ + 500;

	rc = sensor_trigger_set(gyro, &trigger, on_data_ready);
	printf("GYRO-STATS trigger: %d\n", rc);
	while (callbacks < CONFIG_GYRO_STATS_SAMPLES && k_uptime_get() < until) {
		(void)k_sem_take(&data_ready, K_MSEC(100));
	}
	printf("GYRO-STATS callbacks %d\n", callbacks);
	printf("GYRO-STATS done %d\n", callbacks < CONFIG_GYRO_STATS_SAMPLES
						  ? callbacks : CONFIG_GYRO_STATS_SAMPLES);
#else
	int64_t next = k_uptime_ticks();
	const int64_t period = CONFIG_SYS_CLOCK_TICKS_PER_SEC / CONFIG_GYRO_STATS_ODR_HZ;
	int n = 0;

	for (; n < CONFIG_GYRO_STATS_SAMPLES; n++) {
		if (print_sample(gyro, n) != 0) {
			break;
		}
		next += period;
		k_sleep(K_TIMEOUT_ABS_TICKS(next));
	}
	printf("GYRO-STATS done %d\n", n);
#endif
	return 0;
}
