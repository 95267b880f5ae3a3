/* Self-check of the codec's number printer (numfmt.c), run by
 * tests/python/test_cli.py: every finite double must read back bitwise equal,
 * be the shortest of %.15g/%.16g/%.17g that does, and look like a real
 * ('.' or exponent); NaN and infinities must never be printed as numbers.
 * Exit status 0 when all hold; prints the first failure otherwise. */
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

static long longer_than_shortest = 0;

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
        /* Compare with the shortest of %.15g..%.17g that round-trips: Grisu2 may
         * give one digit more in rare cases, never more than 17 digits. */
        char ref[40];
        int p, mine = 0, theirs = 0;
        const char* q;
        snprintf(ref, sizeof ref, "%.15g", v);
        if (strtod(ref, NULL) == v) {
            for (p = 14; p >= 1; --p) {
                snprintf(ref, sizeof ref, "%.*g", p, v);
                if (strtod(ref, NULL) != v) break;
            }
            theirs = p + 1;
        } else {
            snprintf(ref, sizeof ref, "%.16g", v);
            theirs = strtod(ref, NULL) == v ? 16 : 17;
        }
        for (q = buf; *q && *q != 'e'; ++q)
            if (*q >= '0' && *q <= '9') ++mine;
        /* strip leading zeros ("0.000123") and trailing zeros ("100.0") */
        {
            const char* s0 = buf;
            int lead = 0, trail = 0;
            const char* end = strchr(buf, 'e') ? strchr(buf, 'e') : buf + strlen(buf);
            while (*s0 == '-' || *s0 == '0' || *s0 == '.') {
                if (*s0 == '0') ++lead;
                ++s0;
            }
            while (end > s0 && (end[-1] == '0' || end[-1] == '.')) {
                if (end[-1] == '0') ++trail;
                --end;
            }
            mine -= lead + trail;
        }
        if (mine > 17) {
            printf("FAIL %a printed %s: %d digits\n", v, buf, mine);
            return 1;
        }
        if (mine > theirs) ++longer_than_shortest;
        if (mine < theirs) {
            printf("FAIL %a printed %s: %d digits, but no %d-digit form reads back\n", v, buf, mine, mine);
            return 1;
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
    for (i = 0; i < 300000 && failures < 10; ++i) {
        uint64_t bits = next_u64();
        double v;
        memcpy(&v, &bits, sizeof v);
        if (!isfinite(v)) continue;
        failures += check(v);
        /* Values of the kind the core prints: moderate magnitudes, small ones, integers. */
        failures += check((double)(next_u64() >> 11) * 0x1.0p-53 * 200.0 - 100.0);
        failures += check(ldexp((double)(next_u64() >> 11), (int)(next_u64() % 200) - 300));
    }
    if (failures) {
        printf("%ld failures\n", failures);
        return 1;
    }
    /* Grisu2 is shortest for ~99.9% of doubles; allow 1%. */
    if (longer_than_shortest > 9000) {
        printf("FAIL %ld of 900,000 numbers are longer than the shortest form\n", longer_than_shortest);
        return 1;
    }
    printf("numfmt: ok (900,000 random doubles round-trip bitwise; %ld one digit longer than the shortest)\n",
           longer_than_shortest);
    return 0;
}
