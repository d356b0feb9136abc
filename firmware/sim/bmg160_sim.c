/* bmg160_sim: runs the bmg160-emu firmware in simavr and plays the I2C master.
 *
 * Usage:
 *   bmg160_sim FIRMWARE.elf [--scl HZ]                       line protocol on stdin/stdout
 *   bmg160_sim FIRMWARE.elf --capture SECONDS --uart FILE [--bw CODE] [--address A]
 *                                                            run, write the UART stream; with
 *                                                            --bw, first write BW over I2C
 *
 * Line protocol (one request per line, one answer per line, "ok ..." or "err ..."):
 *   w ADDR HEX            I2C write transaction (HEX: the bytes, e.g. 0f80)   -> ok | nack addr | nack N
 *   r ADDR N              I2C read transaction of N bytes                    -> ok HEX | nack addr
 *   wr ADDR HEX N         combined: write HEX, repeated START, read N bytes  -> ok HEX | nack ...
 *   run CYCLES            advance the simulation                             -> ok CYCLE
 *   peek ADDR N           N bytes of data memory (SRAM addresses)            -> ok HEX
 *   uart                  UART bytes sent since the last request             -> ok HEX
 *   cycle                 current cycle                                      -> ok CYCLE
 *   bench SECONDS N       back-to-back combined reads of N bytes at 0x02     -> ok TRANSACTIONS CYCLES
 *   quit
 *
 * Debian's simavr 1.6 TWI model is not used as a bus: its slave path reports a write's
 * address phase as data, ends slave transmit after one byte and reports STOP as 0xA8.
 * The harness is the bus instead: before each bus event it clears the model's state
 * (avr_twi_t.state, public in avr_twi.h) so the model's TWCR handler stays inert, writes
 * the status code the ATmega328P data sheet gives for the event into TWSR (and the
 * received byte into TWDR), raises the TWI vector with avr_raise_interrupt(), and runs
 * the core until the firmware clears TWINT (clock stretching). See docs/firmware.md. */
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "avr_twi.h"
#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_cycle_timers.h"
#include "sim_elf.h"
#include "sim_interrupts.h"
#include "sim_irq.h"

#define F_CPU 16000000UL
#define STRETCH_LIMIT_CYCLES 200000UL /* 12.5 ms: a firmware that never answers */

static avr_t *avr;
static avr_twi_t *twi;
static uint32_t scl_hz = 400000;
static uint32_t scl_cycles;

static FILE *uart_file;
static uint8_t *uart_buf;
static size_t uart_len, uart_cap;

static void die(const char *msg)
{
	fprintf(stderr, "bmg160_sim: %s\n", msg);
	exit(2);
}

/* simavr's raw sleep callback usleep()s to keep wall time; we want full speed. */
static void no_sleep(avr_t *a, avr_cycle_count_t how_long)
{
	(void)a;
	(void)how_long;
}

static void uart_output(struct avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	(void)param;
	if (uart_file) {
		fputc((int)(value & 0xFF), uart_file);
		return;
	}
	if (uart_len == uart_cap) {
		uart_cap = uart_cap ? 2 * uart_cap : 4096;
		uart_buf = realloc(uart_buf, uart_cap);
		if (!uart_buf)
			die("out of memory");
	}
	uart_buf[uart_len++] = (uint8_t)value;
}

/* Workaround: simavr 1.6 leaves TWINT set in TWCR when the firmware writes a one to it,
 * so the harness cannot see the end of clock stretching. The TWCR write handler of the
 * model is wrapped: it still runs, then a written TWINT = 1 clears the flag as on silicon. */
static avr_io_write_t model_twcr_write;
static void *model_twcr_param;
static volatile int twint_released;

static void twcr_write(struct avr_t *a, avr_io_addr_t addr, uint8_t v, void *param)
{
	(void)param;
	twi->state = 0;
	model_twcr_write(a, addr, v, model_twcr_param);
	twi->state = 0;
	if (v & (1 << 7)) {
		a->data[addr] &= (uint8_t)~(1 << 7);
		avr_clear_interrupt(a, &twi->twi);
		twint_released = 1;
	}
}

/* A sleeping core jumps to the next cycle timer; this empty timer makes it stop at the
 * target instead (otherwise a bus bit time could stretch to the next 1 ms tick). */
static avr_cycle_count_t wake_at_target(struct avr_t *a, avr_cycle_count_t when, void *param)
{
	(void)a;
	(void)when;
	(void)param;
	return 0;
}

static void run_until(avr_cycle_count_t target)
{
	if (avr->cycle < target)
		avr_cycle_timer_register(avr, target - avr->cycle, wake_at_target, NULL);
	while (avr->cycle < target) {
		int state = avr_run(avr);
		if (state == cpu_Done || state == cpu_Crashed)
			die("firmware stopped or crashed");
	}
}

static void run_cycles(avr_cycle_count_t n) { run_until(avr->cycle + n); }

/* ---- the bus ------------------------------------------------------------ */

static int slave_acks_address(uint8_t addr7)
{
	uint8_t twcr = avr->data[twi->r_twcr];
	uint8_t mask = (uint8_t)(~avr->data[twi->r_twamr] >> 1);
	if (!avr_regbit_get(avr, twi->twen) || !avr_regbit_get(avr, twi->twea))
		return 0;
	(void)twcr;
	return ((addr7 & mask) == ((avr->data[twi->r_twar] >> 1) & mask));
}

/* One TWI event as the slave sees it: bits on the wire, then TWINT with status. */
static int twi_event(uint8_t status, int bits, int rx_byte)
{
	avr_cycle_count_t deadline;
	run_cycles((avr_cycle_count_t)bits * scl_cycles);
	if (rx_byte >= 0)
		avr->data[twi->r_twdr] = (uint8_t)rx_byte;
	avr->data[twi->r_twsr] = (uint8_t)((avr->data[twi->r_twsr] & 0x07) | status);
	twi->state = 0; /* keep simavr's TWI state machine out of the way */
	twint_released = 0;
	avr_raise_interrupt(avr, &twi->twi);
	deadline = avr->cycle + STRETCH_LIMIT_CYCLES;
	while (!twint_released) {
		int state = avr_run(avr);
		if (state == cpu_Done || state == cpu_Crashed)
			die("firmware stopped or crashed");
		if (avr->cycle > deadline) {
			if (getenv("BMG_SIM_DEBUG"))
				fprintf(stderr, "stuck: TWCR=%02x TWSR=%02x pc=%04x I=%d pending? state=%d\n",
					avr->data[twi->r_twcr], avr->data[twi->r_twsr], avr->pc,
					avr->sreg[S_I], avr->state);
			if (getenv("BMG_SIM_DEBUG"))
				fprintf(stderr, "vector=%d pending=%d enable=%d has_pending=%d\n",
					twi->twi.vector, twi->twi.pending, avr_regbit_get(avr, twi->twi.enable),
					avr_has_pending_interrupts(avr));
			return -1;
		}
	}
	twi->state = 0;
	return avr->data[twi->r_twdr];
}

static int hexval(char c)
{
	if (c >= '0' && c <= '9')
		return c - '0';
	if (c >= 'a' && c <= 'f')
		return c - 'a' + 10;
	if (c >= 'A' && c <= 'F')
		return c - 'A' + 10;
	return -1;
}

static int parse_hex(const char *s, uint8_t *out, int max)
{
	int n = 0;
	while (s[0] && s[1] && n < max) {
		int hi = hexval(s[0]), lo = hexval(s[1]);
		if (hi < 0 || lo < 0)
			return -1;
		out[n++] = (uint8_t)(hi << 4 | lo);
		s += 2;
	}
	return n;
}

static void print_hex(const uint8_t *data, size_t n)
{
	static const char digits[] = "0123456789abcdef";
	for (size_t i = 0; i < n; i++) {
		putchar(digits[data[i] >> 4]);
		putchar(digits[data[i] & 15]);
	}
}

/* Returns 0, or -1 for an address NACK, or k+1 when data byte k was NACKed. */
static int bus_write_phase(uint8_t addr7, const uint8_t *data, int n)
{
	if (!slave_acks_address(addr7)) {
		run_cycles(10UL * scl_cycles);
		return -1;
	}
	if (twi_event(0x60, 10, -1) < 0)
		return -2;
	for (int i = 0; i < n; i++) {
		if (twi_event(0x80, 9, data[i]) < 0)
			return -2;
		if (!avr_regbit_get(avr, twi->twea) && i + 1 < n)
			return i + 2; /* the slave will NACK the next byte */
	}
	return 0;
}

static int bus_read_phase(uint8_t addr7, uint8_t *out, int n)
{
	int v;
	if (!slave_acks_address(addr7)) {
		run_cycles(10UL * scl_cycles);
		return -1;
	}
	v = twi_event(0xA8, 10, -1); /* own SLA+R, ACK returned: load the first byte */
	if (v < 0)
		return -2;
	for (int i = 0; i < n; i++) {
		out[i] = (uint8_t)avr->data[twi->r_twdr];
		/* master ACKs all but the last byte (0xB8), NACKs the last (0xC0) */
		if (twi_event(i + 1 < n ? 0xB8 : 0xC0, 9, -1) < 0)
			return -2;
	}
	return 0;
}

static void bus_stop_after_write(void)
{
	twi_event(0xA0, 1, -1); /* STOP while addressed as slave receiver */
}

static uint64_t transactions;

static int transaction(uint8_t addr7, const uint8_t *wdata, int wn, uint8_t *rdata, int rn,
		       char *err, size_t errlen)
{
	int rc;
	run_cycles(scl_cycles); /* START */
	if (wn > 0 || rn == 0) {
		rc = bus_write_phase(addr7, wdata, wn);
		if (rc == -1) {
			snprintf(err, errlen, "nack addr");
			return -1;
		}
		if (rc == -2) {
			snprintf(err, errlen, "err firmware did not release the bus");
			return -1;
		}
		if (rc > 0) {
			bus_stop_after_write();
			snprintf(err, errlen, "nack %d", rc - 1);
			return -1;
		}
		if (rn > 0) {
			twi_event(0xA0, 1, -1); /* repeated START seen by the addressed slave */
		} else {
			bus_stop_after_write();
			transactions++;
			return 0;
		}
	}
	rc = bus_read_phase(addr7, rdata, rn);
	run_cycles(scl_cycles); /* STOP */
	if (rc == -1) {
		snprintf(err, errlen, "nack addr");
		return -1;
	}
	if (rc == -2) {
		snprintf(err, errlen, "err firmware did not release the bus");
		return -1;
	}
	transactions++;
	return 0;
}

/* ---- set-up and main loop ----------------------------------------------- */

static void load(const char *path)
{
	elf_firmware_t fw;
	memset(&fw, 0, sizeof fw);
	if (elf_read_firmware(path, &fw))
		die("cannot read the firmware ELF");
	avr = avr_make_mcu_by_name("atmega328p");
	if (!avr)
		die("simavr has no atmega328p core");
	avr_init(avr);
	avr_load_firmware(avr, &fw);
	avr->frequency = F_CPU;
	avr->sleep = no_sleep;
	avr->log = 0;
	for (avr_io_t *io = avr->io_port; io; io = io->next)
		if (io->kind && !strcmp(io->kind, "twi"))
			twi = (avr_twi_t *)io;
	if (!twi)
		die("simavr has no TWI module for this core");
	model_twcr_write = avr->io[AVR_DATA_TO_IO(twi->r_twcr)].w.c;
	model_twcr_param = avr->io[AVR_DATA_TO_IO(twi->r_twcr)].w.param;
	if (!model_twcr_write)
		die("simavr's TWI model has no TWCR handler");
	avr->io[AVR_DATA_TO_IO(twi->r_twcr)].w.c = twcr_write;
	uint32_t flags = 0;
	avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
	flags &= ~(uint32_t)(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
	avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
				uart_output, NULL);
}

static void serve(void)
{
	char line[4096], err[128];
	static uint8_t wbuf[2048], rbuf[4096];
	setvbuf(stdout, NULL, _IOFBF, 1 << 16);
	while (fgets(line, sizeof line, stdin)) {
		char cmd[16], hex[4096];
		unsigned long a = 0, b = 0;
		int n;
		if (sscanf(line, "%15s", cmd) != 1)
			continue;
		if (!strcmp(cmd, "quit"))
			break;
		if (!strcmp(cmd, "w") && sscanf(line, "%*s %lx %4095s", &a, hex) == 2) {
			n = parse_hex(hex, wbuf, sizeof wbuf);
			if (n < 0)
				printf("err bad hex\n");
			else if (transaction((uint8_t)a, wbuf, n, NULL, 0, err, sizeof err))
				printf("%s\n", err);
			else
				printf("ok\n");
		} else if (!strcmp(cmd, "r") && sscanf(line, "%*s %lx %lu", &a, &b) == 2) {
			if (b > sizeof rbuf)
				printf("err too many bytes\n");
			else if (transaction((uint8_t)a, NULL, 0, rbuf, (int)b, err, sizeof err))
				printf("%s\n", err);
			else {
				printf("ok ");
				print_hex(rbuf, b);
				printf("\n");
			}
		} else if (!strcmp(cmd, "wr") && sscanf(line, "%*s %lx %4095s %lu", &a, hex, &b) == 3) {
			n = parse_hex(hex, wbuf, sizeof wbuf);
			if (n <= 0 || b == 0 || b > sizeof rbuf)
				printf("err bad arguments\n");
			else if (transaction((uint8_t)a, wbuf, n, rbuf, (int)b, err, sizeof err))
				printf("%s\n", err);
			else {
				printf("ok ");
				print_hex(rbuf, b);
				printf("\n");
			}
		} else if (!strcmp(cmd, "run") && sscanf(line, "%*s %lu", &a) == 1) {
			run_cycles(a);
			printf("ok %llu\n", (unsigned long long)avr->cycle);
		} else if (!strcmp(cmd, "peek") && sscanf(line, "%*s %lx %lu", &a, &b) == 2) {
			if (a + b > avr->ramend + 1UL)
				printf("err outside data memory\n");
			else {
				printf("ok ");
				print_hex(&avr->data[a], b);
				printf("\n");
			}
		} else if (!strcmp(cmd, "uart")) {
			printf("ok ");
			print_hex(uart_buf, uart_len);
			printf("\n");
			uart_len = 0;
		} else if (!strcmp(cmd, "cycle")) {
			printf("ok %llu\n", (unsigned long long)avr->cycle);
		} else if (!strcmp(cmd, "bench") && sscanf(line, "%*s %lu %lu", &a, &b) == 2) {
			avr_cycle_count_t end = avr->cycle + (avr_cycle_count_t)a * F_CPU;
			avr_cycle_count_t start = avr->cycle;
			uint64_t before = transactions;
			uint8_t reg = 0x02;
			if (b == 0 || b > sizeof rbuf) {
				printf("err bad arguments\n");
			} else {
				int failed = 0;
				while (avr->cycle < end && !failed)
					failed = transaction(0x68 | (avr->data[twi->r_twar] >> 1 & 1), &reg, 1,
							     rbuf, (int)b, err, sizeof err);
				if (failed)
					printf("%s\n", err);
				else
					printf("ok %llu %llu\n", (unsigned long long)(transactions - before),
					       (unsigned long long)(avr->cycle - start));
			}
		} else {
			printf("err unknown or malformed request\n");
		}
		fflush(stdout);
	}
}

int main(int argc, char **argv)
{
	const char *elf = NULL, *uart_path = NULL;
	double capture_s = -1;
	int bw_code = -1;
	unsigned long address = 0x68;
	for (int i = 1; i < argc; i++) {
		if (!strcmp(argv[i], "--scl") && i + 1 < argc)
			scl_hz = (uint32_t)strtoul(argv[++i], NULL, 10);
		else if (!strcmp(argv[i], "--capture") && i + 1 < argc)
			capture_s = strtod(argv[++i], NULL);
		else if (!strcmp(argv[i], "--bw") && i + 1 < argc)
			bw_code = (int)strtol(argv[++i], NULL, 0);
		else if (!strcmp(argv[i], "--address") && i + 1 < argc)
			address = strtoul(argv[++i], NULL, 0);
		else if (!strcmp(argv[i], "--uart") && i + 1 < argc)
			uart_path = argv[++i];
		else if (!elf)
			elf = argv[i];
		else
			die("usage: bmg160_sim FIRMWARE.elf [--scl HZ] [--capture SECONDS --uart FILE]");
	}
	if (!elf)
		die("usage: bmg160_sim FIRMWARE.elf [--scl HZ] [--capture SECONDS --uart FILE]");
	if (scl_hz < 1000 || scl_hz > 1000000)
		die("--scl must be 1000..1000000 Hz");
	scl_cycles = (uint32_t)(F_CPU / scl_hz);
	{
		/* simavr prints its loader messages on stdout: keep stdout for answers */
		int saved = dup(1);
		dup2(2, 1);
		load(elf);
		fflush(stdout);
		dup2(saved, 1);
		close(saved);
	}
	if (capture_s >= 0) {
		if (!uart_path)
			die("--capture needs --uart FILE");
		uart_file = fopen(uart_path, "wb");
		if (!uart_file)
			die("cannot open the --uart file");
		if (bw_code >= 0) {
			char err[128];
			uint8_t cmd[2] = {0x10, (uint8_t)bw_code};
			run_cycles(F_CPU / 100); /* let the firmware boot (10 ms) */
			if (transaction((uint8_t)address, cmd, 2, NULL, 0, err, sizeof err))
				die(err);
		}
		run_until((avr_cycle_count_t)(capture_s * F_CPU));
		fclose(uart_file);
		return 0;
	}
	serve();
	return 0;
}
