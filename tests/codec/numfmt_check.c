/* Self-check of the codec's number printer (numfmt.c), run by
 * tests/python/test_cli.py: every finite double must read back bitwise equal,
 * have no more significant digits than the shortest %.{p}g that does, and,
 * when it has as many, its digits (the nearest of that length: snprintf
 * rounds correctly); it may have fewer only at a power of two, whose lower
 * neighbour is nearer (a shorter decimal can lie in the wider upper half of
 * its interval). It must look like a real ('.' or exponent); NaN and
 * infinities must never be printed as numbers. Exit status 0 when all hold;
 * prints the first failure otherwise. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "codec_internal.h"

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static uint64_t next_u64(void) { /* xorshift64* */
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return rng_state * 2685821657736338717ull;
}

static long shorter_at_powers = 0;

static int check(double v) {
    char buf[32];
    double back;
    int n = ntsj_format_double(buf, v);
    if (n <= 0 || n >= 32 || (int)strlen(buf) != n) {
        printf("FAIL length %d for %a\n", n, v);
        return 1;
    }
    back = strtod(buf, NULL);
    if (memcmp(&back, &v, sizeof v) != 0) {
        printf("FAIL %a printed %s reads back %a\n", v, buf, back);
        return 1;
    }
    if (!strchr(buf, '.') && !strchr(buf, 'e')) {
        printf("FAIL %s does not look like a real\n", buf);
        return 1;
    }
    if (strlen(buf) > 25) {
        printf("FAIL %s is too long\n", buf);
        return 1;
    }
    if (v != 0.0) {
        /* The shortest %.{p}g that reads back (snprintf's digits: the nearest
         * of p digits) against ours, their significant digits alone. */
        char ref[40], want[24], mine[24];
        int p, d = 0;
        const char* q;
        for (p = 1; p <= 17; ++p) {
            snprintf(ref, sizeof ref, "%.*e", p - 1, v);
            if (strtod(ref, NULL) == v) break;
        }
        for (q = ref; *q && *q != 'e'; ++q)
            if (*q >= '0' && *q <= '9') want[d++] = *q;
        want[d] = '\0';
        d = 0;
        for (q = buf; *q && *q != 'e'; ++q)
            if (*q >= '0' && *q <= '9' && (d > 0 || *q != '0')) mine[d++] = *q; /* (no leading zeros) */
        while (d > 1 && mine[d - 1] == '0') --d; /* nor trailing ("100.0") */
        mine[d] = '\0';
        if (d > p) {
            printf("FAIL %a printed %s: %d digits, %s has %d\n", v, buf, d, ref, p);
            return 1;
        }
        if (d == p && strcmp(mine, want) != 0) {
            printf("FAIL %a printed %s, the nearest of %d digits is %s\n", v, buf, p, ref);
            return 1;
        }
        if (d < p) {
            uint64_t bits;
            memcpy(&bits, &v, sizeof bits);
            if ((bits & ((1ull << 52) - 1)) != 0) { /* not a power of two */
                printf("FAIL %a printed %s: %d digits, fewer than the nearest's %s\n", v, buf, d, ref);
                return 1;
            }
            ++shorter_at_powers;
        }
    }
    return 0;
}

int main(void) {
    static const double fixed[] = {0.0, 1.0, -1.0, 0.1, 0.2, 0.30000000000000004, 1e300, -1e-300, 5e-324,
                                   2.2250738585072014e-308, 1.7976931348623157e308, 123456789012345678.0,
                                   9007199254740993.0, 1.0 / 3.0, 100.0, 1e21, 1e22};
    static const struct { double v; const char* text; } exact[] = {
        {0.0, "0.0"}, {1.0, "1.0"}, {0.1, "0.1"}, {100.0, "100.0"}, {-2.5, "-2.5"}, {1e300, "1e+300"}};
    char buf[32];
    long i, failures = 0;
    double neg_zero = -0.0;
    for (i = 0; i < (long)(sizeof fixed / sizeof fixed[0]); ++i) failures += check(fixed[i]) + check(-fixed[i]);
    for (i = 0; i < (long)(sizeof exact / sizeof exact[0]); ++i) {
        ntsj_format_double(buf, exact[i].v);
        if (strcmp(buf, exact[i].text) != 0) {
            printf("FAIL %.17g printed %s, expected %s\n", exact[i].v, buf, exact[i].text);
            ++failures;
        }
    }
    ntsj_format_double(buf, neg_zero);
    if (strcmp(buf, "-0.0") != 0 || !signbit(strtod(buf, NULL))) {
        printf("FAIL -0.0 printed %s\n", buf);
        ++failures;
    }
    ntsj_format_double(buf, (double)NAN);
    if (strcmp(buf, "null") != 0) { printf("FAIL NaN printed %s\n", buf); ++failures; }
    ntsj_format_double(buf, (double)INFINITY);
    if (strcmp(buf, "null") != 0) { printf("FAIL Inf printed %s\n", buf); ++failures; }
    for (i = -1074; i <= 1023 && failures < 10; ++i) { /* the intervals' asymmetric ends, the subnormals' */
        const double two = ldexp(1.0, (int)i);
        failures += check(two) + check(nextafter(two, 0.0)) + check(nextafter(two, INFINITY));
    }
    for (i = 0; i < 300000 && failures < 10; ++i) {
        uint64_t bits = next_u64();
        double v;
        memcpy(&v, &bits, sizeof v);
        if (!isfinite(v)) continue;
        failures += check(v);
        /* Values of the kind the core prints: moderate magnitudes, small ones, integers. */
        failures += check((double)(next_u64() >> 11) * 0x1.0p-53 * 200.0 - 100.0);
        failures += check(ldexp((double)(next_u64() >> 11), (int)(next_u64() % 200) - 300));
        /* short decimals (their removed digits exact zeros), small integers */
        failures += check((double)(next_u64() % 100000000u) / (double)(1u << (next_u64() % 12)));
        failures += check((double)(next_u64() % 1000000u) * pow(10.0, (double)(int)(next_u64() % 40) - 20));
    }
    if (failures) {
        printf("%ld failures\n", failures);
        return 1;
    }
    printf("numfmt: ok (every power of two and its neighbours, and 1,500,000 random doubles: the shortest digits that "
           "read back bitwise, the nearest of their length; %ld shorter still at a power of two)\n",
           shorter_at_powers);
    return 0;
}
