/* FIFO of spec 6.5: bypass / FIFO / stream modes, frame-aligned reads, fifo_frames
 * leave when their last byte is read, empty pattern 0x00 0x80 per word. */
#include "bmg160_registers.h"
#include "fifo.h"

static uint8_t fifo_frames[FIFO_CAPACITY][6];
static uint8_t fifo_head;       /* index of the oldest frame */
static uint8_t fifo_count;      /* complete fifo_frames stored */
static uint8_t fifo_byte_pos;   /* next byte within the frame being read */
static uint8_t fifo_overrun_flag;

void fifo_clear(void)
{
	fifo_head = 0;
	fifo_count = 0;
	fifo_byte_pos = 0;
}

void fifo_clear_overrun(void) { fifo_overrun_flag = 0; }

void fifo_end_transaction(void)
{
	if (!fifo_count)
		fifo_byte_pos = 0;
}
uint8_t fifo_frame_count(void) { return fifo_count; }
uint8_t fifo_overrun(void) { return fifo_overrun_flag; }

void fifo_push(const int16_t counts[3], uint8_t mode)
{
	uint8_t slot;
	if (mode == 1) {                 /* FIFO: stop when full */
		if (fifo_count >= FIFO_CAPACITY) {
			fifo_overrun_flag = 1;
			return;
		}
	} else if (mode == 2) {          /* stream: drop the oldest */
		if (fifo_count >= FIFO_CAPACITY) {
			fifo_head = (uint8_t)((fifo_head + 1) % FIFO_CAPACITY);
			fifo_count--;
			fifo_byte_pos = 0;
			fifo_overrun_flag = 1;
		}
	} else {                         /* bypass (and reserved 3): newest only */
		fifo_clear();
	}
	slot = (uint8_t)((fifo_head + fifo_count) % FIFO_CAPACITY);
	for (uint8_t i = 0; i < 3; i++) {
		fifo_frames[slot][2 * i] = (uint8_t)counts[i];
		fifo_frames[slot][2 * i + 1] = (uint8_t)((uint16_t)counts[i] >> 8);
	}
	fifo_count++;
}

uint8_t fifo_read_byte(uint8_t config0, uint8_t config1)
{
	uint8_t select = (config1 & BMG_FIFO_CONFIG_1_FIFO_DATA_SELECT_MASK)
		>> BMG_FIFO_CONFIG_1_FIFO_DATA_SELECT_SHIFT;
	uint8_t data_bytes = select ? 2 : 6;
	uint8_t frame_size = data_bytes + ((config0 & BMG_FIFO_CONFIG_0_TAG_MASK) ? 2 : 0); /* tag (4.26) */
	uint8_t value;

	if (fifo_byte_pos >= data_bytes) {
		value = 0x00;                 /* tag bytes: pin states, no pins modelled */
	} else if (fifo_count == 0) {
		value = (fifo_byte_pos & 1) ? 0x80 : 0x00; /* empty pattern, -32768 */
	} else {
		uint8_t offset = select ? (uint8_t)(2 * (select - 1) + fifo_byte_pos) : fifo_byte_pos;
		value = fifo_frames[fifo_head][offset];
	}
	if (++fifo_byte_pos >= frame_size) {
		fifo_byte_pos = 0;
		if (fifo_count) {
			fifo_head = (uint8_t)((fifo_head + 1) % FIFO_CAPACITY);
			fifo_count--;
		}
	}
	return value;
}
