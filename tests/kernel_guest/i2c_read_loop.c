/* SPDX-License-Identifier: MIT
 * Register reads in a loop through /dev/i2c-N (I2C_RDWR: write the register, read LEN
 * bytes; or with a 6th argument "smbus", the SMBus I2C block read that SMBus-only adapters
 * such as i2c-stub take), timed one by one: how fast a guest program reaches the model (bmg160-emu,
 * tools/bench_virtio_i2c.py and tests/test_kernel_virtio_i2c.py). Prints one line:
 * reads=N seconds=S per_s=R p50_us=P p99_us=Q max_us=M
 * With a last argument "nolat", no clock is read around each read (under UML each clock
 * read is a ptrace stop, and under its time travel a step of the guest's clock): the loop
 * is timed from outside (tools/bench_uml.py) and nothing is printed.
 */
#include <fcntl.h>
#include <linux/i2c-dev.h>
#include <linux/i2c.h>
#include <string.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>

static double now_s(void)
{
	struct timespec t;

	clock_gettime(CLOCK_MONOTONIC, &t);
	return t.tv_sec + t.tv_nsec * 1e-9;
}

static int compare(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;

	return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
	char path[32];
	unsigned char reg, buf[64];
	struct i2c_msg msgs[2];
	struct i2c_rdwr_ioctl_data rdwr = { msgs, 2 };
	union i2c_smbus_data block;
	struct i2c_smbus_ioctl_data smbus = { I2C_SMBUS_READ, 0, I2C_SMBUS_I2C_BLOCK_DATA, &block };
	int fd, i, n, len, addr, use_smbus;
	double *lat, start, t0;

	int nolat = argc > 6 && !strcmp(argv[argc - 1], "nolat");

	if (nolat)
		argc--;
	if (argc != 6 && argc != 7) {
		fprintf(stderr, "usage: %s BUS ADDR REG LEN COUNT [smbus] [nolat]\n", argv[0]);
		return 2;
	}
	snprintf(path, sizeof(path), "/dev/i2c-%s", argv[1]);
	addr = (int)strtol(argv[2], NULL, 0);
	reg = (unsigned char)strtol(argv[3], NULL, 0);
	len = atoi(argv[4]);
	n = atoi(argv[5]);
	use_smbus = argc == 7 && !strcmp(argv[6], "smbus");
	if (len < 1 || len > (use_smbus ? 32 : (int)sizeof(buf)) || n < 1) {
		fprintf(stderr, "bad LEN or COUNT\n");
		return 2;
	}
	fd = open(path, O_RDWR);
	if (fd < 0) {
		perror(path);
		return 1;
	}
	if (use_smbus && ioctl(fd, I2C_SLAVE_FORCE, addr) < 0) {
		perror("I2C_SLAVE_FORCE");
		return 1;
	}
	smbus.command = reg;
	lat = malloc(sizeof(double) * n);
	msgs[0] = (struct i2c_msg){ .addr = addr, .flags = 0, .len = 1, .buf = &reg };
	msgs[1] = (struct i2c_msg){ .addr = addr, .flags = I2C_M_RD, .len = len, .buf = buf };
	start = nolat ? 0 : now_s();
	for (i = 0; i < n; i++) {
		t0 = nolat ? 0 : now_s();
		if (use_smbus) {
			block.block[0] = len;
			if (ioctl(fd, I2C_SMBUS, &smbus) < 0) {
				perror("I2C_SMBUS");
				return 1;
			}
		} else if (ioctl(fd, I2C_RDWR, &rdwr) != 2) {
			perror("I2C_RDWR");
			return 1;
		}
		lat[i] = nolat ? 0 : now_s() - t0;
	}
	if (nolat)
		return 0;
	start = now_s() - start;
	qsort(lat, n, sizeof(double), compare);
	printf("reads=%d seconds=%.4f per_s=%.1f p50_us=%.1f p99_us=%.1f max_us=%.1f\n", n, start,
	       n / start, lat[n / 2] * 1e6, lat[(int)(n * 0.99)] * 1e6, lat[n - 1] * 1e6);
	return 0;
}
