/* On-chip noise of the paper's model: white + first-order Gauss-Markov +
 * random walk per axis, plus the constant bias (docs/noise-model.md). */
#ifndef BMG_NOISE_H
#define BMG_NOISE_H
#include <stdint.h>

void noise_init(void);
/* One output sample in deg/s for the three axes at the ODR of bw_code. */
void noise_sample(uint8_t bw_code, float rate_dps[3]);
/* A unit normal (exposed for the statistics tests of the generator). */
float noise_normal(void);

#endif
