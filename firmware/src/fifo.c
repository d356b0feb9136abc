/* FIFO of spec 6.5: bypass / FIFO / stream modes, frame-aligned reads, frames
 * leave when their last byte is read, empty pattern 0x00 0x80 per word. */
#include "fifo.h"

static uint8_t frames[FIFO_CAPACITY][6];
static uint8_t head;       /* index of the oldest frame */
static uint8_t count;      /* complete frames stored */
static uint8_t byte_pos;   /* next byte within the frame being read */
static uint8_t overrun;

void fifo_clear(void)
{
	head = 0;
	count = 0;
	byte_pos = 0;
}

void fifo_clear_overrun(void) { overrun = 0; }
uint8_t fifo_frame_count(void) { return count; }
uint8_t fifo_overrun(void) { return overrun; }

void fifo_push(const int16_t counts[3], uint8_t mode)
{
	uint8_t slot;
	if (mode == 1) {                 /* FIFO: stop when full */
		if (count >= FIFO_CAPACITY) {
			overrun = 1;
			return;
		}
	} else if (mode == 2) {          /* stream: drop the oldest */
		if (count >= FIFO_CAPACITY) {
			head = (uint8_t)((head + 1) % FIFO_CAPACITY);
			count--;
			byte_pos = 0;
			overrun = 1;
		}
	} else {                         /* bypass (and reserved 3): newest only */
		fifo_clear();
	}
	slot = (uint8_t)((head + count) % FIFO_CAPACITY);
	for (uint8_t i = 0; i < 3; i++) {
		frames[slot][2 * i] = (uint8_t)counts[i];
		frames[slot][2 * i + 1] = (uint8_t)((uint16_t)counts[i] >> 8);
	}
	count++;
}

uint8_t fifo_read_byte(uint8_t config0, uint8_t config1)
{
	uint8_t select = config1 & 0x03;
	uint8_t data_bytes = select ? 2 : 6;
	uint8_t frame_size = data_bytes + ((config0 & 0x80) ? 2 : 0); /* tag (4.26) */
	uint8_t value;

	if (byte_pos >= data_bytes) {
		value = 0x00;                 /* tag bytes: pin states, no pins modelled */
	} else if (count == 0) {
		value = (byte_pos & 1) ? 0x80 : 0x00; /* empty pattern, -32768 */
	} else {
		uint8_t offset = select ? (uint8_t)(2 * (select - 1) + byte_pos) : byte_pos;
		value = frames[head][offset];
	}
	if (++byte_pos >= frame_size) {
		byte_pos = 0;
		if (count) {
			head = (uint8_t)((head + 1) % FIFO_CAPACITY);
			count--;
		}
	}
	return value;
}
