/* xoshiro256** with splitmix64 seeding; polar-method normals. */
#include "msid/msid_rng.h"
#include "msid/msid_dmath.h"

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static inline uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

void msid_rng_seed(msid_rng *r, uint64_t seed)
{
    uint64_t x = seed;
    for (int i = 0; i < 4; ++i) r->s[i] = splitmix64(&x);
    r->spare = 0.0;
    r->has_spare = 0;
}

uint64_t msid_rng_u64(msid_rng *r)
{
    uint64_t *s = r->s;
    const uint64_t result = rotl(s[1] * 5u, 7) * 9u;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double msid_rng_uniform(msid_rng *r)
{
    return (double)(msid_rng_u64(r) >> 11) * (1.0 / 9007199254740992.0);
}

double msid_rng_normal(msid_rng *r)
{
    if (r->has_spare) {
        r->has_spare = 0;
        return r->spare;
    }
    double u, v, q;
    do {
        u = 2.0 * msid_rng_uniform(r) - 1.0;
        v = 2.0 * msid_rng_uniform(r) - 1.0;
        q = u * u + v * v;
    } while (q >= 1.0 || q == 0.0);
    const double f = msid_sqrt(-2.0 * msid_log(q) / q);
    r->spare = v * f;
    r->has_spare = 1;
    return u * f;
}
