/*
 * Copyright (c) 2026 The bmg160-emu contributors
 * SPDX-License-Identifier: MIT
 *
 * The client side of the serve protocol, version 1 (docs/serve-protocol.md):
 * a blocking UNIX-socket connection, one request answered before the next.
 *
 * Host code: built with the host libc, into the native simulator runner (the
 * module's "bottom") and into the CI's stand-alone client. It knows nothing
 * of Zephyr.
 */

#include "bmg160_emu_link.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

enum {
	HELLO = 0x01,
	I2C = 0x02,
	SPI = 0x03,
	SYNC = 0x04,
	SET_RATE = 0x05,
	BYE = 0x06,
	REPLY = 0x80,
	EVENT = 0xC0,
	ERROR = 0xFF,
};

#define HEADER_SIZE 20
#define RESULT_SIZE 24
#define MAX_PAYLOAD (1u << 20)
#define MAX_I2C_MESSAGES 42

/* little-endian fields, whatever the host */
static void put16(uint8_t *p, uint16_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
}

static void put32(uint8_t *p, uint32_t v)
{
	put16(p, (uint16_t)v);
	put16(p + 2, (uint16_t)(v >> 16));
}

static void put64(uint8_t *p, uint64_t v)
{
	put32(p, (uint32_t)v);
	put32(p + 4, (uint32_t)(v >> 32));
}

static uint16_t get16(const uint8_t *p)
{
	return (uint16_t)(p[0] | p[1] << 8);
}

static uint32_t get32(const uint8_t *p)
{
	return get16(p) | (uint32_t)get16(p + 2) << 16;
}

static uint64_t get64(const uint8_t *p)
{
	return get32(p) | (uint64_t)get32(p + 4) << 32;
}

static int broken(struct bmg_emu_link *link, const char *fmt, ...)
{
	va_list args;

	va_start(args, fmt);
	vsnprintf(link->error, sizeof(link->error), fmt, args);
	va_end(args);
	if (link->fd >= 0) {
		close(link->fd);
		link->fd = -1;
	}
	return BMG_EMU_LINK_BROKEN;
}

static int send_all(struct bmg_emu_link *link, const uint8_t *data, size_t size)
{
	while (size > 0) {
		ssize_t sent = send(link->fd, data, size, MSG_NOSIGNAL);

		if (sent < 0 && errno == EINTR) {
			continue;
		}
		if (sent <= 0) {
			return broken(link, "bmg160-emu: lost the server: %s", strerror(errno));
		}
		data += sent;
		size -= (size_t)sent;
	}
	return 0;
}

/* Reads through the link's inbox: one recv() usually brings a whole reply. */
static int recv_all(struct bmg_emu_link *link, uint8_t *data, size_t size)
{
	while (size > 0) {
		uint32_t ready = link->inbox_end - link->inbox_at;
		ssize_t got;

		if (ready > 0) {
			uint32_t take = ready < size ? ready : (uint32_t)size;

			if (data != NULL) {
				memcpy(data, link->inbox + link->inbox_at, take);
				data += take;
			}
			link->inbox_at += take;
			size -= take;
			continue;
		}
		link->inbox_at = link->inbox_end = 0;
		got = recv(link->fd, link->inbox, sizeof(link->inbox), 0);
		if (got < 0 && errno == EINTR) {
			continue;
		}
		if (got <= 0) {
			return broken(link, "bmg160-emu: the server closed the connection%s%s",
				      got < 0 ? ": " : "", got < 0 ? strerror(errno) : "");
		}
		link->inbox_end = (uint32_t)got;
	}
	return 0;
}

/* The server's ERROR message: its one line becomes the link's error. */
static int refused(struct bmg_emu_link *link, uint32_t length)
{
	uint8_t text[256];
	uint32_t keep = length < sizeof(text) - 1 ? length : sizeof(text) - 1;

	if (keep < 8 || recv_all(link, text, keep)) {
		return broken(link, "bmg160-emu: the server ended the connection");
	}
	text[keep] = '\0';
	return broken(link, "bmg160-emu: the server: %s", (const char *)text + 8);
}

/* The reply's body is read into `body` (at most `room` bytes past the result);
 * EVENT messages met on the way update the levels. Returns the reply status.
 */
static int transact(struct bmg_emu_link *link, uint8_t type, uint64_t time_ns,
		    const uint8_t *payload, uint32_t size, const uint8_t *tail, uint32_t tail_size,
		    uint8_t *body, uint32_t room)
{
	uint8_t header[HEADER_SIZE];
	uint8_t result[RESULT_SIZE];
	int rc;

	static uint8_t message[HEADER_SIZE + 4 + 8 * MAX_I2C_MESSAGES + 8192];

	if (link->fd < 0) {
		return BMG_EMU_LINK_BROKEN;
	}
	if ((size_t)size + tail_size > sizeof(message) - HEADER_SIZE) {
		return -EINVAL;
	}
	link->seq++;
	/* one send for the whole message: the server answers it in one wake-up */
	put32(message, size + tail_size);
	put16(message + 4, type);
	put16(message + 6, 0);
	put32(message + 8, link->seq);
	put64(message + 12, time_ns);
	if (size > 0) {
		memcpy(message + HEADER_SIZE, payload, size);
	}
	if (tail_size > 0) {
		memcpy(message + HEADER_SIZE + size, tail, tail_size);
	}
	rc = send_all(link, message, HEADER_SIZE + size + tail_size);
	if (rc) {
		return rc;
	}
	for (;;) {
		uint32_t length;
		uint16_t got_type;

		rc = recv_all(link, header, sizeof(header));
		if (rc) {
			return rc;
		}
		length = get32(header);
		got_type = get16(header + 4);
		if (length > MAX_PAYLOAD) {
			return broken(link, "bmg160-emu: a reply of %u bytes: out of step", length);
		}
		if (got_type == ERROR) {
			return refused(link, length);
		}
		if (length < RESULT_SIZE) {
			return broken(link, "bmg160-emu: a reply of %u bytes: too short", length);
		}
		rc = recv_all(link, result, sizeof(result));
		if (rc) {
			return rc;
		}
		link->levels = get64(result + 8);
		link->next_change_ns = get64(result + 16);
		link->time_ns = get64(header + 12);
		length -= RESULT_SIZE;
		if (got_type == EVENT) {
			link->events++;
			if (length) {
				return broken(link, "bmg160-emu: an EVENT with a body");
			}
			continue;
		}
		if (got_type != (type | REPLY) || get32(header + 8) != link->seq) {
			return broken(link, "bmg160-emu: reply 0x%02x to request %u, expected "
				      "0x%02x to %u", got_type, get32(header + 8),
				      type | REPLY, link->seq);
		}
		if (length > room) {
			return broken(link, "bmg160-emu: a reply of %u data bytes for %u", length,
				      room);
		}
		if (length && recv_all(link, body, length)) {
			return BMG_EMU_LINK_BROKEN;
		}
		link->detail = get32(result + 4);
		return (int32_t)get32(result);
	}
}

int bmg_emu_link_connect(struct bmg_emu_link *link, const char *path, const char *client)
{
	struct sockaddr_un where = {.sun_family = AF_UNIX};
	uint8_t request[HEADER_SIZE + 4 + 64];
	uint8_t header[HEADER_SIZE];
	uint8_t head[32];
	size_t name = strlen(client) < 64 ? strlen(client) : 64;
	uint32_t length;
	size_t offset;

	memset(link, 0, sizeof(*link));
	link->fd = -1;
	if (strlen(path) >= sizeof(where.sun_path)) {
		return broken(link, "bmg160-emu: socket path too long: %s", path);
	}
	strcpy(where.sun_path, path);
	link->fd = socket(AF_UNIX, SOCK_STREAM, 0);
	if (link->fd < 0 || connect(link->fd, (struct sockaddr *)&where, sizeof(where)) < 0) {
		return broken(link, "bmg160-emu: cannot connect to %s: %s (is `bmg160-emu serve "
			      "--socket %s` running?)", path, strerror(errno), path);
	}
	put32(request, (uint32_t)(4 + name));
	put16(request + 4, HELLO);
	put16(request + 6, 0);
	put32(request + 8, 0);
	put64(request + 12, 0);
	put16(request + HEADER_SIZE, BMG_EMU_PROTOCOL_VERSION);
	put16(request + HEADER_SIZE + 2, 0);
	memcpy(request + HEADER_SIZE + 4, client, name);
	if (send_all(link, request, HEADER_SIZE + 4 + name) ||
	    recv_all(link, header, sizeof(header))) {
		return BMG_EMU_LINK_BROKEN;
	}
	length = get32(header);
	if (get16(header + 4) == ERROR) {
		return refused(link, length);
	}
	if (length < 24 || length > MAX_PAYLOAD) {
		return broken(link, "bmg160-emu: %s did not greet us as a bmg160-emu server", path);
	}
	if (recv_all(link, head, 24)) {
		return BMG_EMU_LINK_BROKEN;
	}
	if (get16(head) != BMG_EMU_PROTOCOL_VERSION) {
		return broken(link, "bmg160-emu: server protocol version %u, ours %u", get16(head),
			      BMG_EMU_PROTOCOL_VERSION);
	}
	link->realtime = get16(head + 2) == 1;
	link->nchips = get16(head + 4);
	link->levels = get64(head + 8);
	link->next_change_ns = get64(head + 16);
	if (link->nchips > BMG_EMU_MAX_CHIPS) {
		return broken(link, "bmg160-emu: %d chips served, at most %d", link->nchips,
			      BMG_EMU_MAX_CHIPS);
	}
	offset = 24;
	for (int i = 0; i < link->nchips; i++) {
		struct bmg_emu_chip *chip = &link->chips[i];
		uint8_t record[6];
		uint8_t text[255];

		if (recv_all(link, record, 6) || recv_all(link, text, record[5])) {
			return BMG_EMU_LINK_BROKEN;
		}
		chip->i2c_bus = record[0];
		chip->i2c_address = record[1];
		chip->spi_cs = record[2];
		chip->pins = record[3];
		chip->chip_id = record[4];
		memcpy(chip->name, text, record[5] < 32 ? record[5] : 32);
		offset += 6u + record[5];
	}
	if (offset != length) {
		return broken(link, "bmg160-emu: a HELLO reply of %u bytes, read %zu", length,
			      offset);
	}
	return 0;
}

int bmg_emu_link_i2c(struct bmg_emu_link *link, uint64_t time_ns,
		     struct bmg_emu_i2c_msg *msgs, int count)
{
	uint8_t table[4 + MAX_I2C_MESSAGES * 8];
	uint8_t data[8192];
	uint8_t reads[8192];
	uint32_t written = 0;
	uint32_t want = 0;
	uint32_t got;
	int rc;

	if (count < 1 || count > MAX_I2C_MESSAGES) {
		return -EINVAL;
	}
	table[0] = 0;
	table[1] = (uint8_t)count;
	put16(table + 2, 0);
	for (int i = 0; i < count; i++) {
		uint8_t *entry = table + 4 + 8 * i;

		put16(entry, msgs[i].addr);
		put16(entry + 2, msgs[i].flags);
		put16(entry + 4, (uint16_t)msgs[i].len);
		put16(entry + 6, 0);
		if (msgs[i].len > sizeof(data)) {
			return -EINVAL;
		}
		if (msgs[i].flags & BMG_EMU_I2C_RD) {
			want += msgs[i].len;
		} else {
			if (written + msgs[i].len > sizeof(data)) {
				return -EINVAL;
			}
			memcpy(data + written, msgs[i].buf, msgs[i].len);
			written += msgs[i].len;
		}
	}
	if (want > sizeof(reads)) {
		return -EINVAL;
	}
	rc = transact(link, I2C, time_ns, table, 4 + 8 * (uint32_t)count, data, written, reads,
		      want);
	if (rc == BMG_EMU_LINK_BROKEN) {
		return rc;
	}
	/* the read messages that completed, in order */
	got = 0;
	for (int i = 0; i < count && i < (int)link->detail; i++) {
		if (msgs[i].flags & BMG_EMU_I2C_RD) {
			memcpy(msgs[i].buf, reads + got, msgs[i].len);
			got += msgs[i].len;
		}
	}
	return rc;
}

int bmg_emu_link_spi(struct bmg_emu_link *link, uint64_t time_ns, uint8_t cs, uint16_t mode,
		     const uint8_t *tx, uint8_t *rx, uint32_t len)
{
	uint8_t head[12];
	uint8_t sink[4096];
	int rc;

	if (len > sizeof(sink)) {
		return -EINVAL;
	}
	if (tx == NULL) {
		mode |= BMG_EMU_SPI_NO_TX;
	}
	head[0] = 0;
	head[1] = cs;
	head[2] = 8;
	head[3] = 0;
	put16(head + 4, mode);
	put16(head + 6, 0);
	put32(head + 8, len);
	rc = transact(link, SPI, time_ns, head, sizeof(head), tx, tx ? len : 0,
		      rx ? rx : sink, len);
	return rc;
}

int bmg_emu_link_sync(struct bmg_emu_link *link, uint64_t time_ns)
{
	return transact(link, SYNC, time_ns, NULL, 0, NULL, 0, NULL, 0);
}

int bmg_emu_link_set_rate(struct bmg_emu_link *link, uint64_t time_ns, uint8_t chip,
			  double x_dps, double y_dps, double z_dps)
{
	uint8_t body[32] = {chip};
	double rate[3] = {x_dps, y_dps, z_dps};

	for (int i = 0; i < 3; i++) {
		uint64_t bits;

		memcpy(&bits, &rate[i], sizeof(bits));
		put64(body + 8 + 8 * i, bits);
	}
	return transact(link, SET_RATE, time_ns, body, sizeof(body), NULL, 0, NULL, 0);
}

int bmg_emu_link_bye(struct bmg_emu_link *link, uint64_t time_ns)
{
	int rc = transact(link, BYE, time_ns, NULL, 0, NULL, 0, NULL, 0);

	bmg_emu_link_close(link);
	return rc;
}

void bmg_emu_link_close(struct bmg_emu_link *link)
{
	if (link->fd >= 0) {
		close(link->fd);
		link->fd = -1;
	}
}

int bmg_emu_link_find_i2c(const struct bmg_emu_link *link, uint8_t address)
{
	for (int i = 0; i < link->nchips; i++) {
		if (link->chips[i].i2c_address == address) {
			return i;
		}
	}
	return -1;
}

int bmg_emu_link_find_spi(const struct bmg_emu_link *link, uint8_t cs)
{
	for (int i = 0; i < link->nchips; i++) {
		if (link->chips[i].spi_cs == cs) {
			return i;
		}
	}
	return -1;
}

void bmg_emu_i2c_flags_from_zephyr(const uint8_t *zephyr_flags, int count, uint16_t *flags)
{
	for (int i = 0; i < count; i++) {
		uint8_t z = zephyr_flags[i];
		uint16_t f = 0;

		if (z & BMG_EMU_ZEPHYR_I2C_MSG_READ) {
			f |= BMG_EMU_I2C_RD;
		}
		if (z & BMG_EMU_ZEPHYR_I2C_MSG_ADDR_10_BITS) {
			f |= BMG_EMU_I2C_TEN;
		}
		if (z & BMG_EMU_ZEPHYR_I2C_MSG_STOP) {
			f |= BMG_EMU_I2C_STOP;
		}
		if (i > 0 && !(z & BMG_EMU_ZEPHYR_I2C_MSG_RESTART) &&
		    !(zephyr_flags[i - 1] & BMG_EMU_ZEPHYR_I2C_MSG_STOP) &&
		    !((z ^ zephyr_flags[i - 1]) & BMG_EMU_ZEPHYR_I2C_MSG_READ)) {
			f |= BMG_EMU_I2C_NOSTART;
		}
		flags[i] = f;
	}
}

int bmg_emu_spi_mode_from_zephyr(uint32_t operation, uint16_t *mode)
{
	uint32_t word = (operation & BMG_EMU_ZEPHYR_SPI_WORD_SIZE_MASK) >>
			BMG_EMU_ZEPHYR_SPI_WORD_SIZE_SHIFT;
	uint16_t m = 0;

	if (word != 8 || (operation & (0x3u << 16))) {
		return -ENOTSUP; /* 8-bit words on one data line only */
	}
	if (operation & BMG_EMU_ZEPHYR_SPI_MODE_CPOL) {
		m |= BMG_EMU_SPI_CPOL;
	}
	if (operation & BMG_EMU_ZEPHYR_SPI_MODE_CPHA) {
		m |= BMG_EMU_SPI_CPHA;
	}
	if (operation & BMG_EMU_ZEPHYR_SPI_MODE_LOOP) {
		m |= BMG_EMU_SPI_LOOP;
	}
	if (operation & BMG_EMU_ZEPHYR_SPI_TRANSFER_LSB) {
		m |= BMG_EMU_SPI_LSB_FIRST;
	}
	if (operation & BMG_EMU_ZEPHYR_SPI_HALF_DUPLEX) {
		m |= BMG_EMU_SPI_3WIRE;
	}
	if (operation & BMG_EMU_ZEPHYR_SPI_HOLD_ON_CS) {
		m |= BMG_EMU_SPI_KEEP_CS;
	}
	if (operation & BMG_EMU_ZEPHYR_SPI_CS_ACTIVE_HIGH) {
		m |= BMG_EMU_SPI_CS_HIGH;
	}
	*mode = m;
	return 0;
}

int bmg_emu_link_spi_bufs(struct bmg_emu_link *link, uint64_t time_ns, uint8_t cs, uint16_t mode,
			  const struct bmg_emu_buf *tx, int ntx, const struct bmg_emu_buf *rx,
			  int nrx)
{
	uint8_t out[4096];
	uint8_t in[4096];
	size_t tx_len = 0;
	size_t rx_len = 0;
	size_t len;
	size_t at;
	int rc;

	for (int i = 0; i < ntx; i++) {
		tx_len += tx[i].len;
	}
	for (int i = 0; i < nrx; i++) {
		rx_len += rx[i].len;
	}
	len = tx_len > rx_len ? tx_len : rx_len;
	if (len > sizeof(out)) {
		return -EINVAL;
	}
	memset(out, 0, len);
	at = 0;
	for (int i = 0; i < ntx; i++) {
		if (tx[i].buf != NULL) {
			memcpy(out + at, tx[i].buf, tx[i].len);
		}
		at += tx[i].len;
	}
	rc = bmg_emu_link_spi(link, time_ns, cs, mode, ntx > 0 ? out : NULL, in, (uint32_t)len);
	if (rc == BMG_EMU_LINK_BROKEN) {
		return rc;
	}
	at = 0;
	for (int i = 0; i < nrx; i++) {
		if (rx[i].buf != NULL) {
			memcpy(rx[i].buf, in + at, rx[i].len);
		}
		at += rx[i].len;
	}
	return rc;
}
