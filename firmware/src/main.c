/* bmg160-emu firmware: an ATmega328P that answers as a BMG160 on I2C, makes
 * the identified noise on chip and streams every sample on the UART.
 *
 * Interrupts do the bus (TWI), the ODR clock (Timer1) and the UART queue; the
 * main loop computes samples. A sample computed during a bus transaction is
 * published when the transaction ends, so a transaction always sees one
 * consistent sample (spec 6.1). */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "config.h"
#include "fifo.h"
#include "millis.h"
#include "noise.h"
#include "regmap.h"
#include "sampler.h"
#include "twi_slave.h"
#include "uart_stream.h"
#include "bmg160_params.h"

#define BACKLOG_LIMIT 4 /* periods the main loop may catch up on */
/* Samples waiting for the end of a long transaction (a 600-byte FIFO burst at 400 kHz lasts
 * 13.5 ms, almost three periods at 200 Hz): up to 16 of them reach the FIFO, in order. */
#define PENDING_MAX 16

static int16_t pending_counts[PENDING_MAX][3];
static volatile uint8_t pending;
static uint8_t pending_epoch;

static int16_t to_counts(float rate_dps, uint8_t range_code)
{
	float counts = rate_dps * pgm_read_float(&bmg_sensitivity_lsb_per_dps[range_code]);
	if (counts >= 32767.0f)
		return 32767;
	if (counts <= -32768.0f)
		return -32768;
	return (int16_t)lrintf(counts);
}

void twi_transaction_ended(void)
{
	if (pending_epoch == sampler_epoch)
		for (uint8_t i = 0; i < pending; i++)
			regmap_publish(pending_counts[i]);
	pending = 0;
}

static uint8_t append_long(char *out, int32_t value)
{
	ltoa(value, out, 10);
	return (uint8_t)strlen(out);
}

static void stream_sample(uint32_t index, const float rate_dps[3])
{
	char line[48];
	uint8_t n;
	if (uart_room() < sizeof line) { /* the longest line is 44 bytes: drop it unformatted */
		sampler_stats.uart_dropped++;
		return;
	}
	ultoa(index, line, 10);
	n = (uint8_t)strlen(line);
	for (uint8_t i = 0; i < 3; i++) {
		line[n++] = ' ';
		n += append_long(&line[n], lrintf(rate_dps[i] * 1000.0f)); /* mdps */
	}
	line[n++] = '\n';
	if (!uart_send_line(line, n))
		sampler_stats.uart_dropped++;
}

static void produce_sample(uint32_t index, uint8_t epoch)
{
	float rate_dps[3];
	int16_t counts[3];
	uint8_t range = regmap_range_code();

	int16_t offsets[3];

	noise_sample(regmap_bw_code(), rate_dps);
	regmap_offsets(offsets);
	for (uint8_t i = 0; i < 3; i++) {
		/* offset LSB = one LSB of the +-2000 deg/s range (spec 6.9) */
		rate_dps[i] += offsets[i] * (1.0f / pgm_read_float(&bmg_sensitivity_lsb_per_dps[0]));
		counts[i] = to_counts(rate_dps[i], range);
	}
	cli();
	if (epoch != sampler_epoch) {
		sei(); /* the data path stopped or restarted meanwhile: drop it */
		return;
	}
	if (twi_busy()) {
		if (pending && pending_epoch != epoch)
			pending = 0;
		if (pending == PENDING_MAX) { /* keep the newest: drop the oldest */
			memmove(pending_counts[0], pending_counts[1], sizeof pending_counts[0] * (PENDING_MAX - 1));
			pending--;
		}
		memcpy(pending_counts[pending], counts, sizeof counts);
		pending++;
		pending_epoch = epoch;
	} else {
		regmap_publish(counts);
	}
	sampler_stats.produced++;
	sei();
	stream_sample(index, rate_dps);
}

static void stream_banner(void)
{
	static const char banner[] = "# bmg160-emu firmware profile=" BMG_PROFILE_NAME
		" mode=" BMG_NOISE_MODE_NAME " fields=index x_mdps y_mdps z_mdps\n";
	uart_send_line(banner, (uint8_t)(sizeof banner - 1));
}

int main(void)
{
	uart_init();
	millis_init();
	noise_init();
	sampler_init();
	regmap_reset();
	twi_slave_init(BMG_I2C_ADDRESS);
	set_sleep_mode(SLEEP_MODE_IDLE);
	sei();
	stream_banner();

	for (;;) {
		uint32_t newest;
		uint8_t due, epoch;
		cli();
		if (!sampler_has_due()) {
			sleep_enable();
			sei();
			sleep_cpu(); /* the instruction after sei runs first: no lost wake-up */
			sleep_disable();
			continue;
		}
		sei();
		due = sampler_take_due(&newest, &epoch);
		if (due > BACKLOG_LIMIT) {
			sampler_stats.missed += due - 1;
			due = 1;
		}
		while (due)
			produce_sample(newest - --due, epoch);
	}
}
