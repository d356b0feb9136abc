/* The output data rate clock (Timer1 in CTC mode) and the sample bookkeeping. */
#ifndef BMG_SAMPLER_H
#define BMG_SAMPLER_H
#include <stdint.h>

struct sampler_stats {
	uint32_t index;          /* output periods of the data path since power-on */
	uint32_t produced;       /* samples computed and published */
	uint32_t missed;         /* periods skipped because the CPU fell behind */
	uint32_t uart_dropped;   /* lines not sent because the UART queue was full */
};

extern volatile struct sampler_stats sampler_stats;
/* Changes whenever the data path stops or restarts: a sample computed before that must
 * not be published after it (suspend freezes the registers, reset clears them). */
extern volatile uint8_t sampler_epoch;

void sampler_init(void);
/* Restart the data path: the first new sample comes delay_ms after now. */
void sampler_restart(uint16_t delay_ms);
/* Stop producing samples (suspend modes); registers keep their last values. */
void sampler_stop(void);
/* Follow a new BW code from the next period on. */
void sampler_set_bw(uint8_t bw_code);
/* Forget periods elapsed but not yet published (their sample predates a configuration
 * write that must not see it, e.g. a FIFO reset or an ODR change). */
void sampler_discard_backlog(void);
/* Periods elapsed and not yet processed (read and cleared atomically), and the
 * index of the newest of them. */
uint8_t sampler_take_due(uint32_t *newest_index, uint8_t *epoch);
/* Non-zero if a period is waiting (call with interrupts disabled before sleeping). */
uint8_t sampler_has_due(void);
/* True while the new-data pulse of the last published sample lasts. */
uint8_t sampler_data_pulse(void);
/* True once the data path runs and its start-up time has passed (BIST rate_ok). */
uint8_t sampler_valid(void);
void sampler_mark_published(void);

#endif
