/* The bus side of spec section 2: the first byte of a write sets the register
 * pointer, further bytes are written with auto-increment; reads start at the
 * pointer, which persists between transactions (split read form) and stays at
 * 0x3F (FIFO_DATA). Bit 7 of the register byte is not decoded: a transaction
 * starts at (pointer & BMG_REGISTER_ADDRESS_MASK), as the Python model's does,
 * and a burst runs on from there without wrapping (saturating at 0xFF). SCL is
 * stretched by the hardware while TWINT is set, so every register byte is
 * computed at the moment it is needed. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/twi.h>

#include "bmg160_registers.h"
#include "config.h"
#include "fifo.h"
#include "regmap.h"
#include "twi_slave.h"

#define TWCR_ACK (_BV(TWINT) | _BV(TWEA) | _BV(TWEN) | _BV(TWIE))

static volatile uint8_t pointer;
static uint8_t expect_pointer;
static volatile uint8_t busy;
volatile uint32_t twi_transactions; /* completed transactions, for benchmarks */

static inline void advance(void)
{
	/* stays on FIFO_DATA (spec 2.4); saturates at 0xFF past the map */
	if (pointer != BMG_REG_FIFO_DATA && pointer != 0xFF)
		pointer++;
}

void twi_slave_init(uint8_t address7)
{
	TWAR = (uint8_t)(address7 << 1); /* no general call */
	TWCR = TWCR_ACK & (uint8_t)~_BV(TWINT);
}

uint8_t twi_busy(void) { return busy; }

ISR(TWI_vect)
{
	switch (TW_STATUS) {
	case TW_SR_SLA_ACK:
	case TW_SR_ARB_LOST_SLA_ACK:
		busy = 1;
		expect_pointer = 1;
		break;
	case TW_SR_DATA_ACK:
		if (expect_pointer) {
			pointer = TWDR & BMG_REGISTER_ADDRESS_MASK;
			expect_pointer = 0;
		} else {
			regmap_write(pointer, TWDR);
			advance();
		}
		break;
	case TW_ST_SLA_ACK:
	case TW_ST_ARB_LOST_SLA_ACK:
		busy = 1;
		/* a read starts at the decoded address: a pointer left past 0x7F by an
		 * earlier burst wraps as the model's does */
		pointer &= BMG_REGISTER_ADDRESS_MASK;
		/* fall through: load the first byte */
	case TW_ST_DATA_ACK:
		TWDR = regmap_read(pointer);
		advance();
		break;
	case TW_ST_DATA_NACK:
	case TW_ST_LAST_DATA:
	case TW_SR_STOP:
		busy = 0;
		twi_transactions++;
		fifo_end_transaction();
		twi_transaction_ended();
		break;
	case TW_BUS_ERROR:
		busy = 0;
		TWCR = TWCR_ACK | _BV(TWSTO);
		return;
	default:
		break;
	}
	TWCR = TWCR_ACK;
}
