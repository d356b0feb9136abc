/* Timer1 ticks at the ODR of the BW register (spec 5.3). Timer1 runs at
 * F_CPU / 8 = 2 MHz, so every ODR of the table is an exact compare value. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "config.h"
#include "sampler.h"

#define TIMER_HZ (F_CPU / 8UL)
/* data_int pulse length: 280..400 us on the sister part (spec 6.3, B088). */
#define DATA_PULSE_US 300UL
#define DATA_PULSE_COUNTS ((uint16_t)(DATA_PULSE_US * (TIMER_HZ / 1000000UL)))

static const uint16_t odr_hz[8] = {2000, 2000, 1000, 400, 200, 100, 200, 100};

volatile struct sampler_stats sampler_stats;
volatile uint8_t sampler_epoch;
static volatile uint16_t startup_ticks;   /* periods still to wait before sampling */
static volatile uint8_t running;
static volatile uint8_t due;
static volatile uint16_t pulse_start;
static volatile uint8_t pulse_tick;
static volatile uint8_t tick_low;         /* low byte of the period counter */
static uint8_t pulse_valid;
static uint8_t current_bw;

static uint16_t period_counts(uint8_t bw_code)
{
	return (uint16_t)(TIMER_HZ / odr_hz[bw_code & 7]);
}

ISR(TIMER1_COMPA_vect)
{
	tick_low++;
	if (!running)
		return;
	if (startup_ticks) {
		if (--startup_ticks)
			return;
	}
	sampler_stats.index++;
	if (due < 255)
		due++;
}

void sampler_init(void)
{
	current_bw = 0;
	OCR1A = period_counts(0) - 1;
	TCCR1A = 0;
	TCCR1B = _BV(WGM12) | _BV(CS11);   /* CTC, clk/8 */
	TIMSK1 = _BV(OCIE1A);
}

void sampler_restart(uint16_t delay_ms)
{
	ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
		uint32_t periods = ((uint32_t)delay_ms * odr_hz[current_bw & 7] + 999UL) / 1000UL;
		TCNT1 = 0;
		startup_ticks = periods ? (uint16_t)periods : 1;
		due = 0;
		running = 1;
		sampler_epoch++;
		pulse_valid = 0;
	}
}

void sampler_stop(void)
{
	ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
		running = 0;
		due = 0;
		sampler_epoch++;
		pulse_valid = 0;
	}
}

void sampler_set_bw(uint8_t bw_code)
{
	ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
		uint16_t top = period_counts(bw_code) - 1;
		if (startup_ticks) { /* keep the start-up time, not the period count */
			uint32_t ticks = ((uint32_t)startup_ticks * odr_hz[bw_code & 7]
				+ odr_hz[current_bw] - 1) / odr_hz[current_bw];
			startup_ticks = ticks ? (uint16_t)ticks : 1;
		}
		current_bw = bw_code & 7;
		OCR1A = top;
		if (TCNT1 > top)
			TCNT1 = 0; /* CTC would otherwise run on to 0xFFFF */
	}
}

uint8_t sampler_take_due(uint32_t *newest_index, uint8_t *epoch)
{
	uint8_t n;
	ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
		n = due;
		due = 0;
		*newest_index = sampler_stats.index;
		*epoch = sampler_epoch;
	}
	return n;
}

uint8_t sampler_has_due(void) { return due; }

void sampler_mark_published(void)
{
	pulse_start = TCNT1;
	pulse_tick = tick_low;
	pulse_valid = 1;
}

void sampler_discard_backlog(void)
{
	ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
		due = 0;
		sampler_epoch++;
	}
}

uint8_t sampler_valid(void) { return running && !startup_ticks; }

uint8_t sampler_data_pulse(void)
{
	if (!pulse_valid)
		return 0;
	if (pulse_tick != tick_low || (uint16_t)(TCNT1 - pulse_start) >= DATA_PULSE_COUNTS) {
		pulse_valid = 0;
		return 0;
	}
	return 1;
}
