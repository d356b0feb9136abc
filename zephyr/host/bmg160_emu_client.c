/*
 * Copyright (c) 2026 The bmg160-emu contributors
 * SPDX-License-Identifier: MIT
 *
 * bmg160_emu_client: the module's host half without Zephyr, driven by lines
 * on stdin, one answer line each on stdout. Built by the CI's tests
 * (tests/test_serve_c_client.py) with the host compiler alone:
 *
 *   cc -o client zephyr/host/bmg160_emu_client.c zephyr/src/bmg160_emu_link.c -Izephyr/src
 *   client SOCKET < commands
 *
 * Commands (T: the simulator's time in ns; numbers in hex where they are
 * bytes, flags or modes; DATA: hex bytes, LEN: a read length):
 *   i2c T ADDR FLAGS:DATA|FLAGS:LEN ...   protocol (Linux i2c_msg) flags
 *   zi2c T ADDR ZFLAGS:DATA|ZFLAGS:LEN ...  Zephyr i2c_msg flags, translated
 *   spi T CS MODE DATA|-LEN               protocol mode bits
 *   zspi T CS OPERATION TX RX             a Zephyr operation word and buffer
 *                                         sets: TX "hex,hex" ('.' a NULL
 *                                         buffer of 1 byte, '-' no set), RX
 *                                         "len,len" ('.n' NULL, '-' no set)
 *   sync T | rate T CHIP X Y Z | bye T
 * Answer: rc=R detail=D levels=L next=N|never time=T data=HEX
 */

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bmg160_emu_link.h"

#define MAX_BYTES 4096

static struct bmg_emu_link link;

static size_t unhex(const char *text, uint8_t *out, size_t room)
{
	size_t n = 0;

	while (text[0] && text[1] && n < room) {
		char pair[3] = {text[0], text[1], 0};

		out[n++] = (uint8_t)strtoul(pair, NULL, 16);
		text += 2;
	}
	return n;
}

static void answer(int rc, const uint8_t *data, size_t size)
{
	printf("rc=%d detail=%u levels=%llx next=", rc, link.detail,
	       (unsigned long long)link.levels);
	if (link.next_change_ns == BMG_EMU_NEVER) {
		printf("never");
	} else {
		printf("%llu", (unsigned long long)link.next_change_ns);
	}
	printf(" time=%llu data=", (unsigned long long)link.time_ns);
	for (size_t i = 0; i < size; i++) {
		printf("%02x", data[i]);
	}
	printf("\n");
	fflush(stdout);
}

/* "i2c"/"zi2c" T ADDR entries... */
static int do_i2c(int zephyr_flags, char **words, int count)
{
	static uint8_t buffers[42][MAX_BYTES];
	struct bmg_emu_i2c_msg msgs[42];
	uint8_t zflags[42];
	uint16_t flags[42];
	uint64_t t = strtoull(words[1], NULL, 0);
	uint16_t address = (uint16_t)strtoul(words[2], NULL, 16);
	uint8_t reads[MAX_BYTES];
	size_t got = 0;
	int n = count - 3;
	int rc;

	if (n < 1 || n > 42) {
		return -1;
	}
	for (int i = 0; i < n; i++) {
		char *entry = words[3 + i];
		char *body = strchr(entry, ':');
		unsigned long f = strtoul(entry, NULL, 16);

		if (body == NULL) {
			return -1;
		}
		body++;
		flags[i] = (uint16_t)f;
		zflags[i] = (uint8_t)f;
		msgs[i].addr = address;
		msgs[i].buf = buffers[i];
		if (zephyr_flags ? (f & BMG_EMU_ZEPHYR_I2C_MSG_READ) : (f & BMG_EMU_I2C_RD)) {
			msgs[i].len = (uint32_t)strtoul(body, NULL, 0);
			memset(buffers[i], 0xEE, MAX_BYTES);
		} else {
			msgs[i].len = (uint32_t)unhex(body, buffers[i], MAX_BYTES);
		}
	}
	if (zephyr_flags) {
		bmg_emu_i2c_flags_from_zephyr(zflags, n, flags);
	}
	for (int i = 0; i < n; i++) {
		msgs[i].flags = flags[i];
	}
	rc = bmg_emu_link_i2c(&link, t, msgs, n);
	for (int i = 0; i < n && rc != BMG_EMU_LINK_BROKEN; i++) {
		if ((flags[i] & BMG_EMU_I2C_RD) && i < (int)link.detail &&
		    got + msgs[i].len <= sizeof(reads)) {
			memcpy(reads + got, msgs[i].buf, msgs[i].len);
			got += msgs[i].len;
		}
	}
	answer(rc, reads, got);
	return rc == BMG_EMU_LINK_BROKEN ? 1 : 0;
}

static int do_spi(char **words, int count)
{
	uint8_t tx[MAX_BYTES];
	uint8_t rx[MAX_BYTES];
	uint64_t t;
	size_t len;
	int rc;

	if (count != 5) {
		return -1;
	}
	t = strtoull(words[1], NULL, 0);
	if (words[4][0] == '-') {
		len = strtoul(words[4] + 1, NULL, 0);
		rc = bmg_emu_link_spi(&link, t, (uint8_t)strtoul(words[2], NULL, 0),
				      (uint16_t)strtoul(words[3], NULL, 16), NULL, rx, (uint32_t)len);
	} else {
		len = unhex(words[4], tx, sizeof(tx));
		rc = bmg_emu_link_spi(&link, t, (uint8_t)strtoul(words[2], NULL, 0),
				      (uint16_t)strtoul(words[3], NULL, 16), tx, rx, (uint32_t)len);
	}
	answer(rc, rx, rc == BMG_EMU_LINK_BROKEN ? 0 : len);
	return rc == BMG_EMU_LINK_BROKEN ? 1 : 0;
}

/* a Zephyr spi_buf_set from "hex,hex" (tx) or "len,len" (rx) */
static int buffer_set(char *text, int tx, struct bmg_emu_buf *set, uint8_t (*store)[256])
{
	int n = 0;

	if (strcmp(text, "-") == 0) {
		return -1; /* no set at all */
	}
	for (char *item = strtok(text, ","); item && n < 8; item = strtok(NULL, ",")) {
		if (item[0] == '.') {
			set[n].buf = NULL;
			set[n].len = tx ? 1 : strtoul(item + 1, NULL, 0);
		} else if (tx) {
			set[n].buf = store[n];
			set[n].len = unhex(item, store[n], 256);
		} else {
			set[n].buf = store[n];
			set[n].len = strtoul(item, NULL, 0);
			memset(store[n], 0xEE, 256);
		}
		n++;
	}
	return n;
}

static int do_zspi(char **words, int count)
{
	static uint8_t tx_store[8][256];
	static uint8_t rx_store[8][256];
	struct bmg_emu_buf tx[8];
	struct bmg_emu_buf rx[8];
	uint8_t out[MAX_BYTES];
	size_t got = 0;
	uint16_t mode;
	int ntx;
	int nrx;
	int rc;

	if (count != 6) {
		return -1;
	}
	if (bmg_emu_spi_mode_from_zephyr((uint32_t)strtoul(words[3], NULL, 16), &mode) != 0) {
		printf("rc=notsup\n");
		fflush(stdout);
		return 0;
	}
	ntx = buffer_set(words[4], 1, tx, tx_store);
	nrx = buffer_set(words[5], 0, rx, rx_store);
	rc = bmg_emu_link_spi_bufs(&link, strtoull(words[1], NULL, 0),
				   (uint8_t)strtoul(words[2], NULL, 0), mode, ntx < 0 ? NULL : tx,
				   ntx < 0 ? 0 : ntx, nrx < 0 ? NULL : rx, nrx < 0 ? 0 : nrx);
	for (int i = 0; i < nrx; i++) {
		if (rx[i].buf != NULL) {
			memcpy(out + got, rx[i].buf, rx[i].len);
			got += rx[i].len;
		}
	}
	answer(rc, out, got);
	return rc == BMG_EMU_LINK_BROKEN ? 1 : 0;
}

int main(int argc, char **argv)
{
	char line[16384];

	if (argc != 2) {
		fprintf(stderr, "usage: %s SOCKET < commands\n", argv[0]);
		return 2;
	}
	if (bmg_emu_link_connect(&link, argv[1], "bmg160_emu_client") != 0) {
		fprintf(stderr, "%s\n", link.error);
		return 1;
	}
	printf("hello chips=%d realtime=%d levels=%llx\n", link.nchips, link.realtime,
	       (unsigned long long)link.levels);
	for (int i = 0; i < link.nchips; i++) {
		const struct bmg_emu_chip *c = &link.chips[i];

		printf("chip %d %s id=%02x i2c=%02x cs=%02x pins=%u\n", i, c->name, c->chip_id,
		       c->i2c_address, c->spi_cs, c->pins);
	}
	fflush(stdout);
	while (fgets(line, sizeof(line), stdin) != NULL) {
		char *words[64];
		int count = 0;
		int failed = 0;

		for (char *w = strtok(line, " \t\r\n"); w && count < 64; w = strtok(NULL, " \t\r\n")) {
			words[count++] = w;
		}
		if (count < 2) {
			continue;
		}
		if (strcmp(words[0], "i2c") == 0 || strcmp(words[0], "zi2c") == 0) {
			failed = do_i2c(words[0][0] == 'z', words, count);
		} else if (strcmp(words[0], "spi") == 0) {
			failed = do_spi(words, count);
		} else if (strcmp(words[0], "zspi") == 0) {
			failed = do_zspi(words, count);
		} else if (strcmp(words[0], "sync") == 0) {
			int rc = bmg_emu_link_sync(&link, strtoull(words[1], NULL, 0));

			answer(rc, NULL, 0);
			failed = rc == BMG_EMU_LINK_BROKEN;
		} else if (strcmp(words[0], "rate") == 0 && count == 6) {
			int rc = bmg_emu_link_set_rate(&link, strtoull(words[1], NULL, 0),
						       (uint8_t)atoi(words[2]), atof(words[3]),
						       atof(words[4]), atof(words[5]));

			answer(rc, NULL, 0);
			failed = rc == BMG_EMU_LINK_BROKEN;
		} else if (strcmp(words[0], "bye") == 0) {
			answer(bmg_emu_link_bye(&link, strtoull(words[1], NULL, 0)), NULL, 0);
			return 0;
		} else {
			failed = -1;
		}
		if (failed < 0) {
			fprintf(stderr, "bmg160_emu_client: cannot parse: %s\n", words[0]);
			return 2;
		}
		if (failed > 0) {
			fprintf(stderr, "%s\n", link.error);
			return 1;
		}
	}
	return 0;
}
