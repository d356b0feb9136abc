/*
 * Copyright (c) 2026 The bmg160-emu contributors
 * SPDX-License-Identifier: MIT
 *
 * The module's host half on native_sim (the "bottom", built with the host
 * libc into the native simulator runner): the link to `bmg160-emu serve`,
 * every request stamped with the simulated time, and a native simulator HW
 * event at the time the server says a line may next change. When the levels
 * change, the bottom raises the module's interrupt; the top's handler moves
 * the emulated GPIO inputs. The server's clock follows the simulated time, so
 * a seed gives the same counts at any host load, and nothing polls.
 */

#include "bmg160_emu_link.h"

#include <errno.h>
#include <stdlib.h>

#include "irq_ctrl.h"
#include "nsi_hws_models_if.h"
#include "nsi_tasks.h"
#include "nsi_tracing.h"

static struct bmg_emu_link link = {.fd = -1};
static unsigned int link_irq;
static uint64_t told_levels; /* the levels the top was last told about */
static uint64_t line_check_us = NSI_NEVER; /* the HW event: a line may change then */

static uint64_t now_ns(void)
{
	return nsi_hws_get_time() * 1000u; /* the native simulator counts microseconds */
}

static void fail(void)
{
	nsi_print_error_and_exit("%s\n", link.error);
}

/* After every reply: tell the top if the levels moved; wake at the next change. */
static void follow_lines(void)
{
	uint64_t next = link.next_change_ns;
	uint64_t now_us = nsi_hws_get_time();

	if (link.levels != told_levels) {
		told_levels = link.levels;
		hw_irq_ctrl_set_irq(link_irq);
	}
	if (next == BMG_EMU_NEVER) {
		line_check_us = NSI_NEVER;
	} else {
		uint64_t at_us = (next + 999u) / 1000u; /* at or just after the change */

		line_check_us = at_us > now_us ? at_us : now_us + 1u;
	}
	nsi_hws_find_next_event();
}

static void line_check(void)
{
	if (bmg_emu_link_sync(&link, now_ns()) == BMG_EMU_LINK_BROKEN) {
		fail();
	}
	follow_lines();
}

NSI_HW_EVENT(line_check_us, line_check, 200);

int bmg_emu_bottom_open(const char *path, const char *fallback, unsigned int irq)
{
	if (link.fd >= 0) {
		return 0;
	}
	if (path == NULL || path[0] == '\0') {
		path = getenv("BMG160_EMU_SOCKET");
	}
	if (path == NULL || path[0] == '\0') {
		path = fallback;
	}
	if (path == NULL || path[0] == '\0') {
		nsi_print_error_and_exit("bmg160-emu: no server socket: give --bmg160-emu=PATH, "
					 "set BMG160_EMU_SOCKET or CONFIG_BMG160_EMU_SOCKET\n");
	}
	link_irq = irq;
	if (bmg_emu_link_connect(&link, path, "zephyr native_sim") != 0) {
		fail();
	}
	told_levels = link.levels;
	follow_lines();
	return 0;
}

int bmg_emu_bottom_i2c(struct bmg_emu_i2c_msg *msgs, int count)
{
	int rc = bmg_emu_link_i2c(&link, now_ns(), msgs, count);

	if (rc == BMG_EMU_LINK_BROKEN) {
		fail();
	}
	follow_lines();
	return rc;
}

int bmg_emu_bottom_spi(uint8_t cs, uint16_t mode, const struct bmg_emu_buf *tx, int ntx,
		       const struct bmg_emu_buf *rx, int nrx)
{
	int rc = bmg_emu_link_spi_bufs(&link, now_ns(), cs, mode, tx, ntx, rx, nrx);

	if (rc == BMG_EMU_LINK_BROKEN) {
		fail();
	}
	follow_lines();
	return rc;
}

int bmg_emu_bottom_set_rate(uint8_t chip, double x_dps, double y_dps, double z_dps)
{
	int rc = bmg_emu_link_set_rate(&link, now_ns(), chip, x_dps, y_dps, z_dps);

	if (rc == BMG_EMU_LINK_BROKEN) {
		fail();
	}
	follow_lines();
	return rc;
}

uint64_t bmg_emu_bottom_levels(void)
{
	return link.levels;
}

const struct bmg_emu_link *bmg_emu_bottom_link(void)
{
	return &link;
}

static void say_bye(void)
{
	if (link.fd >= 0) {
		(void)bmg_emu_link_bye(&link, now_ns()); /* the server's trace ends whole */
	}
}

NSI_TASK(say_bye, ON_EXIT_PRE, 100);
