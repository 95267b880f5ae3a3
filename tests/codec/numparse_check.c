/* Self-check of the codec's number reader (numparse.c), run by ctest: every
 * JSON number must read as strtod reads it, bit for bit (the nearest double,
 * ties to even), and take exactly the characters of the number; what is not
 * a JSON number must be refused. The numbers: random doubles in every
 * spelling a client writes (%.15g .. %.17g, %e, the shortest), random digit
 * strings of 1-25 digits with exponents around the fast range's edges, the
 * decimals nearest the midpoints between neighbouring doubles (where a
 * rounding mistake shows), exact midpoints (2^53 + odd integers; odd
 * multiples of half an ulp written with 1 to 3 decimals), decimals that are
 * exact doubles, and the
 * edges (0, -0, 19 and 20 digits, 10^+-27 and 10^+-28, overflow, underflow).
 * Exit status 0 when all hold; prints the first failure otherwise. */
#include <float.h>
#include <locale.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "codec_internal.h"

static uint64_t rng_state = 0x2545F4914F6CDD1Dull;
static uint64_t next_u64(void) { /* xorshift64* */
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return rng_state * 2685821657736338717ull;
}

static long checked = 0;

static size_t digits_at(const char* p) {
    size_t n = 0;
    while (p[n] >= '0' && p[n] <= '9') ++n;
    return n;
}

/* The JSON number (RFC 8259 §6) at p, its longest: its length, or 0 when
 * none starts there ("-" alone, "1.", "1e"). */
static size_t json_number_length(const char* p) {
    size_t n = *p == '-', d = digits_at(p + n);
    if (d == 0) return 0;
    n += p[n] == '0' ? 1 : d;
    if (p[n] == '.') {
        if ((d = digits_at(p + n + 1)) == 0) return 0;
        n += 1 + d;
    }
    if (p[n] == 'e' || p[n] == 'E') {
        const size_t sign = p[n + 1] == '+' || p[n + 1] == '-';
        if ((d = digits_at(p + n + 1 + sign)) == 0) return 0;
        n += 1 + sign + d;
    }
    return n;
}

/* `s` must read as strtod reads it and take all of it (or be refused as a
 * whole when it is 64 characters or more and not for the fast way). */
static int check(const char* s) {
    const size_t len = strlen(s);
    double got = 0.0, want = strtod(s, NULL);
    /* the token followed by a character that ends it, and not terminated */
    char buf[160];
    size_t n;
    if (len + 2 > sizeof buf) return 0;
    memcpy(buf, s, len);
    buf[len] = ',';
    n = ntsj_parse_number(buf, buf + len + 1, &got);
    ++checked;
    if (n == 0 && len >= 64) return 0;
    if (n != len) {
        printf("FAIL %s: took %zu characters of %zu\n", s, n, len);
        return 1;
    }
    if (memcmp(&got, &want, sizeof got) != 0) {
        printf("FAIL %s: read %a, strtod %a\n", s, got, want);
        return 1;
    }
    n = ntsj_parse_number(buf, buf + len, &got); /* ending at the buffer's end */
    if (n != len || memcmp(&got, &want, sizeof got) != 0) {
        printf("FAIL %s at the end of its buffer: took %zu, read %a\n", s, n, got);
        return 1;
    }
    /* inside a long text (the word-at-a-time way reads past the number):
     * followed by what a positions array holds, or by digits, an 'e' or a
     * '.' that make it another number or none, which both must agree on */
    {
        static const char* const after[] = {"],[12.345678901234567,-0.5],[1.25,2.5]]}",
                                            "0123456789.0123456789e0123456789.0123456789",
                                            "e+5,1.5,2.5,3.5,4.5,5.5,6.5,7.5,8.5,9.5,10.5",
                                            ".5.5.5.5.5.5.5.5.5.5.5.5.5.5.5.5.5.5.5.5.5.5",
                                            "1.5],[2.5,3.5],[4.5,5.5],[6.5,7.5],[8.5,9.5]"}; /* ("01.5": "0") */
        size_t a;
        for (a = 0; a < sizeof after / sizeof after[0]; ++a) {
            char big[256], tok[256];
            const size_t m = strlen(after[a]);
            size_t expect;
            double w2;
            if (len + m + 1 > sizeof big) continue;
            memcpy(big, s, len);
            memcpy(big + len, after[a], m + 1);
            expect = json_number_length(big);
            n = ntsj_parse_number(big, big + len + m, &got);
            if (expect >= 64 && n == 0) continue; /* (the caller's general way) */
            if (n != expect) {
                printf("FAIL %s: took %zu characters, the number is %zu\n", big, n, expect);
                return 1;
            }
            if (n == 0) continue;
            memcpy(tok, big, n);
            tok[n] = '\0';
            w2 = strtod(tok, NULL);
            if (memcmp(&got, &w2, sizeof got) != 0) {
                printf("FAIL %s: read %a, strtod %a\n", tok, got, w2);
                return 1;
            }
        }
    }
    return 0;
}

static int refused(const char* s) {
    double v = 0.0;
    const size_t n = ntsj_parse_number(s, s + strlen(s), &v);
    if (n != 0) {
        printf("FAIL %s: not a JSON number, but %zu characters taken\n", s, n);
        return 1;
    }
    return 0;
}

static int takes(const char* s, size_t want) {
    double v = 0.0;
    const size_t n = ntsj_parse_number(s, s + strlen(s), &v);
    if (n != want) {
        printf("FAIL %s: took %zu characters, expected %zu\n", s, n, want);
        return 1;
    }
    return 0;
}

static double random_double(void) {
    double v;
    uint64_t bits;
    do {
        bits = next_u64();
        memcpy(&v, &bits, sizeof v);
    } while (!isfinite(v));
    return v;
}

/* a random double of a scale a scene has: |v| in [1e-12, 1e12] */
static double random_coordinate(void) {
    const double m = (double)(next_u64() >> 11) / 9007199254740992.0;
    const int e = (int)(next_u64() % 25) - 12;
    return (next_u64() & 1 ? -1.0 : 1.0) * (1.0 + m) * pow(10.0, e);
}

/* The numbers that go to strtod (more than 19 digits, |exponent| > 27, 64
 * characters or more) read as in the C locale while the process's locale
 * has a decimal comma (NTS_TEST_LOCALE, e.g. de_DE.UTF-8): a host that calls
 * setlocale must not change what a JSON number means. The values expected
 * are read before the locale is set. */
static int comma_locale_check(const char* name) {
    static const char* const texts[] = {
        "1.5e30", "-1.25e-40", "0.12345678901234567890123", "123456789012345678901.5", "2.5e308",
        "1.0000000000000000000000000000000000000000000000000000000000000000000001",
        "-3.14159265358979323846264338327950288419716939937510582097494459230781640628"};
    double want[sizeof texts / sizeof texts[0]];
    size_t k;
    int fails = 0;
    for (k = 0; k < sizeof texts / sizeof texts[0]; ++k) want[k] = strtod(texts[k], NULL);
    if (setlocale(LC_ALL, name) == NULL) {
        printf("FAIL the locale %s cannot be set\n", name);
        return 1;
    }
    if (localeconv()->decimal_point[0] == '.') {
        printf("FAIL the locale %s has a decimal point '.': it tests nothing\n", name);
        setlocale(LC_ALL, "C");
        return 1;
    }
    for (k = 0; k < sizeof texts / sizeof texts[0]; ++k) {
        char buf[256];
        const size_t len = strlen(texts[k]);
        double got = 0.0, whole = 0.0;
        size_t n;
        memset(buf, ' ', sizeof buf);
        memcpy(buf, texts[k], len);
        buf[len] = ',';
        n = ntsj_parse_number(buf, buf + sizeof buf, &got);
        if ((n != len && !(n == 0 && len >= 64)) || (n == len && memcmp(&got, &want[k], sizeof got) != 0) ||
            ntsj_parse_double(texts[k], &whole) != (isfinite(want[k]) ? 0 : 1) ||
            (isfinite(want[k]) && memcmp(&whole, &want[k], sizeof whole) != 0)) {
            printf("FAIL %s in the locale %s: took %zu, read %a and %a, C reads %a\n", texts[k], name, n, got, whole,
                   want[k]);
            ++fails;
        }
    }
    setlocale(LC_ALL, "C");
    if (fails == 0) printf("numparse: read alike in the locale %s (decimal point ',')\n", name);
    return fails;
}

int main(void) {
    static const char* const not_numbers[] = {"", "-", "+1", ".5", "1.", "1.e5", "1e", "1e+", "1E-", "-.5",
                                              "- 1", "inf", "nan", "e5", "-e5", "--1", "\"1\""};
    char s[128];
    int k, j, fails = 0;
    /* the grammar */
    for (k = 0; k < (int)(sizeof not_numbers / sizeof not_numbers[0]); ++k) fails += refused(not_numbers[k]);
    fails += takes("01", 1) + takes("-0.5.5", 4) + takes("1e5e5", 3) + takes("00", 1) + takes("1 ", 1) +
             takes("2x", 1) + takes("-0", 2) + takes("1E+05]", 5) + takes("0x10", 1);
    {
        double v = 1.0;
        ntsj_parse_number("-0.0e7", "-0.0e7" + 6, &v);
        if (!(v == 0.0 && signbit(v))) printf("FAIL -0.0e7 read as %a\n", v), ++fails;
    }
    /* the edges */
    {
        static const char* const edges[] = {
            "0", "-0", "0.0", "0e0", "0e-999999", "-0.000", "1", "-1", "9", "10", "1e27", "1e-27", "1e28", "1e-28",
            "9999999999999999999", "99999999999999999999", "18446744073709551615", "18446744073709551616",
            "9999999999999999999e27", "9999999999999999999e-27", "1000000000000000000e-27", "0.0000000000000000000000000001",
            "123456789012345678.9", "1234567890123456789.0", "1.234567890123456789", "1.2345678901234567890",
            "1.23456789012345678901", "9007199254740993", "9007199254740995", "9007199254740992.5",
            "4503599627370496.5", "4503599627370497.5", "2.2250738585072011e-308", "2.2250738585072014e-308",
            "4.9406564584124654e-324", "2.4703282292062327e-324", "2.4703282292062328e-324", "1.7976931348623157e308",
            "1.7976931348623158e308", "1.7976931348623159e308", "1e309", "-1e309", "1e-400", "1e99999", "1e100000",
            "1e-100000", "1e999999999999", "0.1", "0.2", "0.3", "0.7", "1.1", "3.14159265358979323846",
            "2.718281828459045", "1.5e-5", "-4.25E+3", "1E1", "1e+1", "1e-0", "1e00000000000000000001",
            "0.00000000000000000000000000000000000000000000000000001"};
        for (k = 0; k < (int)(sizeof edges / sizeof edges[0]); ++k) fails += check(edges[k]);
    }
    /* random doubles in the spellings clients write */
    for (k = 0; k < 300000 && fails == 0; ++k) {
        const double v = k % 3 == 0 ? random_double() : random_coordinate();
        snprintf(s, sizeof s, "%.17g", v);
        fails += check(s);
        snprintf(s, sizeof s, "%.16g", v);
        fails += check(s);
        snprintf(s, sizeof s, "%.15g", v);
        fails += check(s);
        snprintf(s, sizeof s, "%.17e", v);
        fails += check(s);
        ntsj_format_double(s, v);
        fails += check(s);
    }
    /* random digit strings: 1-25 digits, a point anywhere, exponents -40..40 */
    for (k = 0; k < 300000 && fails == 0; ++k) {
        const int nd = 1 + (int)(next_u64() % 25), point = (int)(next_u64() % (uint64_t)(nd + 1));
        int n = 0;
        if (next_u64() & 1) s[n++] = '-';
        for (j = 0; j < nd; ++j) {
            if (j == point && j > 0) s[n++] = '.';
            s[n++] = (char)('0' + (j == 0 && nd > 1 && point != 1 ? 1 + next_u64() % 9 : next_u64() % 10));
        }
        if (point == 0 && nd > 1) { /* 0.ddd */
            memmove(s + (s[0] == '-') + 2, s + (s[0] == '-'), (size_t)(n - (s[0] == '-')));
            s[(s[0] == '-')] = '0';
            s[(s[0] == '-') + 1] = '.';
            n += 2;
        }
        if (next_u64() % 4 != 0) n += snprintf(s + n, sizeof s - (size_t)n, "e%d", (int)(next_u64() % 81) - 40);
        s[n] = '\0';
        fails += check(s);
    }
    /* the decimals nearest the midpoints between neighbouring doubles */
    for (k = 0; k < 300000 && fails == 0; ++k) {
        const double v = k % 2 ? fabs(random_coordinate()) : fabs(random_double());
        const double up = nextafter(v, INFINITY);
        const long double mid = ((long double)v + (long double)up) / 2.0L;
        if (!isfinite(up) || LDBL_MANT_DIG < 64) continue;
        for (j = 14; j <= 20; ++j) {
            snprintf(s, sizeof s, "%.*Le", j, mid);
            fails += check(s);
        }
    }
    /* exact midpoints: 2^53 + an odd integer, and their tenths */
    for (k = 0; k < 20000 && fails == 0; ++k) {
        const unsigned long long m = (1ull << 53) + 2ull * (next_u64() % (1ull << 40)) + 1ull;
        snprintf(s, sizeof s, "%llu", m);
        fails += check(s);
        snprintf(s, sizeof s, "%llue-%d", m, (int)(next_u64() % 28));
        fails += check(s);
        snprintf(s, sizeof s, "%llu0000", m);
        fails += check(s);
    }
    /* Where the reader's product cannot decide (numparse.c, divided) and the
     * exact division does: exact ties between two doubles with 1 to 3
     * decimals (an odd multiple of half an ulp in [2^50, 2^53):
     * "4503599627370496.5") and exact doubles one tie step away (".50"),
     * each as a plain decimal and with its last digit moved by one either
     * way; then m 2^-j printed with 0 to 19 decimals (an exact double such
     * as "0.5" or "1.125" when they suffice, else rounded; past 19 digits
     * strtod reads it). */
    for (k = 0; k < 60000 && fails == 0; ++k) {
        const int jd = 1 + (int)(next_u64() % 3); /* decimals: 2^-jd steps */
        const unsigned long long whole = (1ull << (53 - jd)) + next_u64() % (1ull << (53 - jd));
        static const char* const tie[4] = {"", "5", "25", "125"};  /* 2^-jd, written with jd decimals */
        static const char* const half[4] = {"", "0", "50", "250"}; /* an exact double one tie step away */
        const char* const* pick = k % 2 ? half : tie;
        int len = snprintf(s, sizeof s, "%llu.%s", whole, pick[jd]);
        fails += check(s);
        if (s[len - 1] > '0') {
            --s[len - 1];
            fails += check(s);
            s[len - 1] = (char)(s[len - 1] + 2);
            if (s[len - 1] <= '9') fails += check(s);
        }
        len = snprintf(s, sizeof s, "%.*f", (int)(next_u64() % 20), ldexp((double)(next_u64() >> (11 + next_u64() % 40)),
                                                                          -(int)(next_u64() % 20)));
        fails += check(s);
    }
    if (fails == 0) printf("numparse: %ld numbers read as strtod reads them\n", checked);
    if (getenv("NTS_TEST_LOCALE") != NULL) fails += comma_locale_check(getenv("NTS_TEST_LOCALE"));
    return fails == 0 ? 0 : 1;
}
