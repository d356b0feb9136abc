/* Per axis and per sample k (docs/noise-model.md, "The paper's discrete emulator"):
 *   gm(k)   = alpha * gm(k-1) + gm_drive * w_B(k)
 *   rw(k)   = rw(k-1) + rw_step * w_K(k)
 *   out(k)  = bias + white * w_N(k) + gm(k) + rw(k)
 * The coefficients for every BW code come from the generated header, so the
 * same realisation continues when the driver changes the output data rate.
 *
 * Normals: the ziggurat by default (an exact method, about 5 times faster than
 * Box-Muller on the AVR); Marsaglia's polar form of Box-Muller with
 * -DBMG_NORMAL_POLAR; the paper's trigonometric Box-Muller with
 * -DBMG_NORMAL_BOX_MULLER. Uniforms come from xoshiro128+ (upper 24 bits),
 * seeded from the header's seed with splitmix32. */
#include <avr/pgmspace.h>
#include <math.h>

#include "noise.h"

#if !defined(BMG_NORMAL_BOX_MULLER) && !defined(BMG_NORMAL_POLAR)
#define BMG_NORMAL_ZIGGURAT 1 /* the default normal generator */
#endif
#include "bmg160_params.h"

static uint32_t rng[4];
#ifndef BMG_NORMAL_ZIGGURAT
static float spare; /* the second normal of a pair */
static uint8_t have_spare;
#endif
static float gm[3];
static float rw[3];

static inline uint32_t rotl(uint32_t x, uint8_t k) { return (x << k) | (x >> (32 - k)); }

static uint32_t splitmix32(uint32_t *state)
{
	uint32_t z = (*state += 0x9E3779B9UL);
	z = (z ^ (z >> 16)) * 0x85EBCA6BUL;
	z = (z ^ (z >> 13)) * 0xC2B2AE35UL;
	return z ^ (z >> 16);
}

static uint32_t next_u32(void)
{
	uint32_t result = rng[0] + rng[3];
	uint32_t t = rng[1] << 9;
	rng[2] ^= rng[0];
	rng[3] ^= rng[1];
	rng[1] ^= rng[2];
	rng[0] ^= rng[3];
	rng[2] ^= t;
	rng[3] = rotl(rng[3], 11);
	return result;
}

/* Uniform in (0, 1]: 24 random bits, the float mantissa width. */
static float uniform01(void)
{
	return ((float)((next_u32() >> 8) + 1UL)) * (1.0f / 16777216.0f);
}

#ifdef BMG_NORMAL_ZIGGURAT
/* Marsaglia and Tsang's ziggurat (2000), 128 layers, tables from the generated header. The
 * layer index takes the low 7 bits of a draw and the value the upper 25, so the two are
 * independent (Doornik 2005 on the original's shared bits). About 99 % of draws need one
 * 32-bit draw, a table compare and one multiply; the rest use exp or log. */
static inline uint32_t magnitude(int32_t v)
{
	return v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
}

static float ziggurat_tail_or_edge(int32_t hz, uint8_t iz)
{
	for (;;) {
		float x = (float)hz * pgm_read_float(&bmg_zig_wn[iz]);
		if (iz == 0) { /* the tail beyond r */
			float y;
			do {
				x = -logf(uniform01()) * (1.0f / BMG_ZIGGURAT_R);
				y = -logf(uniform01());
			} while (y + y < x * x);
			return hz > 0 ? BMG_ZIGGURAT_R + x : -BMG_ZIGGURAT_R - x;
		}
		float f0 = pgm_read_float(&bmg_zig_fn[iz]);
		float f1 = pgm_read_float(&bmg_zig_fn[iz - 1]);
		if (f0 + uniform01() * (f1 - f0) < expf(-0.5f * x * x))
			return x;
		uint32_t r = next_u32();
		iz = (uint8_t)(r & 0x7F);
		hz = (int32_t)(r & 0xFFFFFF80UL);
		if (magnitude(hz) < pgm_read_dword(&bmg_zig_kn[iz]))
			return (float)hz * pgm_read_float(&bmg_zig_wn[iz]);
	}
}

float noise_normal(void)
{
	uint32_t r = next_u32();
	uint8_t iz = (uint8_t)(r & 0x7F);
	int32_t hz = (int32_t)(r & 0xFFFFFF80UL);
	if (magnitude(hz) < pgm_read_dword(&bmg_zig_kn[iz]))
		return (float)hz * pgm_read_float(&bmg_zig_wn[iz]);
	return ziggurat_tail_or_edge(hz, iz);
}
#elif defined(BMG_NORMAL_BOX_MULLER)
float noise_normal(void)
{
	if (have_spare) {
		have_spare = 0;
		return spare;
	}
	float r = sqrtf(-2.0f * logf(uniform01()));
	float theta = 6.2831853f * uniform01();
	spare = r * sinf(theta);
	have_spare = 1;
	return r * cosf(theta);
}
#else /* BMG_NORMAL_POLAR */
float noise_normal(void)
{
	float u, v, s;
	if (have_spare) {
		have_spare = 0;
		return spare;
	}
	do {
		u = 2.0f * uniform01() - 1.0f;
		v = 2.0f * uniform01() - 1.0f;
		s = u * u + v * v;
	} while (s >= 1.0f || s == 0.0f);
	s = sqrtf(-2.0f * logf(s) / s);
	spare = v * s;
	have_spare = 1;
	return u * s;
}
#endif

void noise_init(void)
{
	uint32_t seed = BMG_SEED;
	for (uint8_t i = 0; i < 4; i++)
		rng[i] = splitmix32(&seed);
#ifndef BMG_NORMAL_ZIGGURAT
	have_spare = 0;
#endif
	for (uint8_t i = 0; i < 3; i++) {
		/* Start the Gauss-Markov term in its stationary distribution. */
		gm[i] = pgm_read_float(&bmg_gm_std_dps[i]) * noise_normal();
		rw[i] = 0.0f;
	}
}

void noise_sample(uint8_t bw_code, float rate_dps[3])
{
	uint8_t code = bw_code & 7;
	for (uint8_t i = 0; i < 3; i++) {
		float white = pgm_read_float(&bmg_noise_white[code][i]) * noise_normal();
		gm[i] = pgm_read_float(&bmg_noise_alpha[code][i]) * gm[i]
			+ pgm_read_float(&bmg_noise_gm_drive[code][i]) * noise_normal();
		rw[i] += pgm_read_float(&bmg_noise_rw_step[code][i]) * noise_normal();
		rate_dps[i] = pgm_read_float(&bmg_bias_dps[i]) + white + gm[i] + rw[i];
	}
}
