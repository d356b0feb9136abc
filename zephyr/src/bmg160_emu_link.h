/*
 * Copyright (c) 2026 The bmg160-emu contributors
 * SPDX-License-Identifier: MIT
 *
 * The link between a simulator and `bmg160-emu serve` (protocol version 1,
 * docs/serve-protocol.md), and the calls between the two halves of the Zephyr
 * module on native_sim.
 *
 * Only <stdint.h> types here: the Zephyr side ("top") and the host side
 * ("bottom", built with the host libc into the native simulator runner) both
 * include this file, and so does the CI's stand-alone C client.
 */

#ifndef BMG160_EMU_LINK_H_
#define BMG160_EMU_LINK_H_

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define BMG_EMU_PROTOCOL_VERSION 1
#define BMG_EMU_MAX_CHIPS 16
#define BMG_EMU_NEVER UINT64_MAX /* next_change_ns when no line change is due */
#define BMG_EMU_NONE 0xFF        /* no I2C address / no SPI chip select */

/* I2C message flags: the Linux struct i2c_msg values (i2c_rdwr) */
#define BMG_EMU_I2C_RD 0x0001
#define BMG_EMU_I2C_TEN 0x0010
#define BMG_EMU_I2C_NOSTART 0x4000 /* continues the previous message: no (re)start */
#define BMG_EMU_I2C_STOP 0x8000

/* SPI mode bits: the Linux spi_device bits, then the protocol's own */
#define BMG_EMU_SPI_CPHA 0x01
#define BMG_EMU_SPI_CPOL 0x02
#define BMG_EMU_SPI_CS_HIGH 0x04
#define BMG_EMU_SPI_LSB_FIRST 0x08
#define BMG_EMU_SPI_3WIRE 0x10
#define BMG_EMU_SPI_LOOP 0x20
#define BMG_EMU_SPI_KEEP_CS 0x0100 /* chip select stays low: the frame goes on */
#define BMG_EMU_SPI_NO_TX 0x0200   /* nothing driven on MOSI */

struct bmg_emu_i2c_msg {
	uint16_t addr;  /* 7-bit address */
	uint16_t flags; /* BMG_EMU_I2C_* */
	uint32_t len;
	uint8_t *buf; /* written from, or read into */
};

/* One chip of the server's board, as its HELLO reply lists it. Its interrupt
 * lines are bits 2i (INT1 / INT3) and 2i+1 (INT2 / INT4) of every `levels`.
 */
struct bmg_emu_chip {
	uint8_t i2c_bus;
	uint8_t i2c_address; /* BMG_EMU_NONE: not on I2C */
	uint8_t spi_cs;      /* BMG_EMU_NONE: not on SPI */
	uint8_t pins;        /* 2 for a gyroscope, 0 for a register-file stand-in */
	uint8_t chip_id;
	char name[33];
};

struct bmg_emu_link {
	int fd;
	uint32_t seq;
	int realtime; /* the server's chips run on wall time */
	int nchips;
	struct bmg_emu_chip chips[BMG_EMU_MAX_CHIPS];
	uint64_t levels;         /* every line's electrical level, as last told */
	uint64_t next_change_ns; /* earliest time a line may change by itself */
	uint64_t time_ns;        /* the chips' time of the last reply */
	uint32_t detail;         /* the last reply's detail (I2C: messages done) */
	uint32_t events;         /* EVENT messages received (real-time servers) */
	char error[200];         /* why the link failed, one line */
	uint8_t inbox[4096];     /* what the server sent and is not read yet */
	uint32_t inbox_at;
	uint32_t inbox_end;
};

/* The link, on the host side. Each returns 0, a negative errno the server
 * answered with (the bus's error: -EREMOTEIO for a NACK, -ETIMEDOUT, -EINVAL),
 * or BMG_EMU_LINK_BROKEN with `error` set: the connection is gone.
 */
#define BMG_EMU_LINK_BROKEN (-1000)

int bmg_emu_link_connect(struct bmg_emu_link *link, const char *path, const char *client);
int bmg_emu_link_i2c(struct bmg_emu_link *link, uint64_t time_ns,
		     struct bmg_emu_i2c_msg *msgs, int count);
int bmg_emu_link_spi(struct bmg_emu_link *link, uint64_t time_ns, uint8_t cs, uint16_t mode,
		     const uint8_t *tx, uint8_t *rx, uint32_t len);
int bmg_emu_link_sync(struct bmg_emu_link *link, uint64_t time_ns);
int bmg_emu_link_set_rate(struct bmg_emu_link *link, uint64_t time_ns, uint8_t chip,
			  double x_dps, double y_dps, double z_dps);
int bmg_emu_link_bye(struct bmg_emu_link *link, uint64_t time_ns);
void bmg_emu_link_close(struct bmg_emu_link *link);
int bmg_emu_link_find_i2c(const struct bmg_emu_link *link, uint8_t address);
int bmg_emu_link_find_spi(const struct bmg_emu_link *link, uint8_t cs);

/* Zephyr's API in the protocol's terms. The Zephyr values are repeated here
 * (the top checks them against Zephyr's headers at build time) so that the
 * translation is host code the CI's client exercises without Zephyr.
 */
#define BMG_EMU_ZEPHYR_I2C_MSG_READ 0x01
#define BMG_EMU_ZEPHYR_I2C_MSG_STOP 0x02
#define BMG_EMU_ZEPHYR_I2C_MSG_RESTART 0x04
#define BMG_EMU_ZEPHYR_I2C_MSG_ADDR_10_BITS 0x08

#define BMG_EMU_ZEPHYR_SPI_MODE_CPOL (1u << 1)
#define BMG_EMU_ZEPHYR_SPI_MODE_CPHA (1u << 2)
#define BMG_EMU_ZEPHYR_SPI_MODE_LOOP (1u << 3)
#define BMG_EMU_ZEPHYR_SPI_TRANSFER_LSB (1u << 4)
#define BMG_EMU_ZEPHYR_SPI_WORD_SIZE_SHIFT 5
#define BMG_EMU_ZEPHYR_SPI_WORD_SIZE_MASK (0x3Fu << 5)
#define BMG_EMU_ZEPHYR_SPI_HALF_DUPLEX (1u << 11)
#define BMG_EMU_ZEPHYR_SPI_HOLD_ON_CS (1u << 12)
#define BMG_EMU_ZEPHYR_SPI_CS_ACTIVE_HIGH (1u << 14)

/* One buffer of a Zephyr spi_buf_set: the same layout as struct spi_buf
 * (buf NULL: nothing sent, or the received bytes dropped).
 */
struct bmg_emu_buf {
	void *buf;
	size_t len;
};

/* Protocol flags for Zephyr's messages to one target: a message with neither
 * RESTART nor a STOP before it continues the previous one (NOSTART), as on the
 * wire: i2c_burst_write's register and data messages are one write.
 */
void bmg_emu_i2c_flags_from_zephyr(const uint8_t *zephyr_flags, int count, uint16_t *flags);

/* The protocol mode for a Zephyr spi_config operation word; -ENOTSUP for a
 * word size other than 8 bits or more than one data line.
 */
int bmg_emu_spi_mode_from_zephyr(uint32_t operation, uint16_t *mode);

/* One SPI transfer from Zephyr's buffer sets: one frame of the longer set's
 * length, tx padded with zeros, rx scattered (spi_transceive's semantics).
 */
int bmg_emu_link_spi_bufs(struct bmg_emu_link *link, uint64_t time_ns, uint8_t cs, uint16_t mode,
			  const struct bmg_emu_buf *tx, int ntx, const struct bmg_emu_buf *rx,
			  int nrx);

/* The bottom (host side, native simulator) as the top calls it. */
int bmg_emu_bottom_open(const char *path, const char *fallback, unsigned int irq);
int bmg_emu_bottom_i2c(struct bmg_emu_i2c_msg *msgs, int count);
int bmg_emu_bottom_spi(uint8_t cs, uint16_t mode, const struct bmg_emu_buf *tx, int ntx,
		       const struct bmg_emu_buf *rx, int nrx);
int bmg_emu_bottom_set_rate(uint8_t chip, double x_dps, double y_dps, double z_dps);
uint64_t bmg_emu_bottom_levels(void);
const struct bmg_emu_link *bmg_emu_bottom_link(void);

#ifdef __cplusplus
}
#endif

#endif /* BMG160_EMU_LINK_H_ */
