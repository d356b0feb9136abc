/* The 100-frame FIFO (spec 6.5). Frames are stored as X, Y, Z words whatever the
 * data select, so a frame costs 6 bytes of RAM: 600 bytes for the full depth. */
#ifndef BMG_FIFO_H
#define BMG_FIFO_H
#include <stdint.h>

#define FIFO_CAPACITY 100 /* frames (spec 6.5, PX4, QC, B08API) */

void fifo_clear(void);
void fifo_push(const int16_t counts[3], uint8_t mode);
uint8_t fifo_read_byte(uint8_t config0, uint8_t config1);
uint8_t fifo_frame_count(void);
uint8_t fifo_overrun(void);
void fifo_clear_overrun(void);
/* After a transaction: the empty pattern starts again at a word boundary. */
void fifo_end_transaction(void);

#endif
