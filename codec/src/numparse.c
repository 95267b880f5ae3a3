/* The codec's number reader: a JSON number (RFC 8259 §6) to the nearest
 * double, ties to even: the bits strtod gives (and so cJSON, which calls
 * it), in less than half its time for the numbers solvers send.
 *
 * Why not strtod alone: a JSON session step is two numbers a node, and
 * glibc's strtod (exact big-number arithmetic for every 16-17 digit
 * number) was 40% of the daemon's time for such a step (docs/benchmarks.md).
 *
 * How it stays exact: a number is w x 10^q with w its significant digits.
 * When w has at most 19 digits (w < 2^64) and |q| <= 27 (5^27 < 2^63), the
 * value is w 5^q 2^q (q >= 0) or w / 5^-q 2^q (q < 0): one 128-bit product,
 * or one division of a 128-bit dividend with its remainder, both exact,
 * rounded once to 53 bits. For q < 0 a product with 10^-q's multiplier
 * decides first (divided): all but the ambiguous 1 in 2^70, which the
 * division decides. Every such value lies in [1e-27, 2^64 1e27], inside the
 * normal doubles, so no underflow or overflow can occur. Anything else (more
 * digits, larger exponents, a compiler without 128-bit integers) is copied
 * and handed to strtod, in the C locale's conventions (c_strtod).
 */
#define _POSIX_C_SOURCE 200809L /* newlocale, uselocale */
#include <locale.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "codec_internal.h"

/* strtod as JSON reads: a '.' is the decimal point whatever locale the host
 * process set (a Python program that called setlocale with a decimal comma
 * made strtod read "1.5e30" as 1, the codec being in its process). The
 * calling thread's locale is the C one for the call alone (uselocale is per
 * thread); without one (newlocale failed), plain strtod. */
static locale_t c_numeric;
static pthread_once_t c_numeric_once = PTHREAD_ONCE_INIT;
static void make_c_numeric(void) { c_numeric = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0); }

static double c_strtod(const char* text, char** end) {
    locale_t before;
    double v;
    (void)pthread_once(&c_numeric_once, make_c_numeric);
    if (c_numeric == (locale_t)0) return strtod(text, end);
    before = uselocale(c_numeric);
    v = strtod(text, end);
    (void)uselocale(before);
    return v;
}

#if defined(__SIZEOF_INT128__)
__extension__ typedef unsigned __int128 u128;
#define NTSJ_HAVE_U128 1
#else
#define NTSJ_HAVE_U128 0
#endif

#define NTSJ_FAST_EXP 27   /* 5^27 < 2^63 */
#define NTSJ_FAST_DIGITS 19 /* 10^19 - 1 < 2^64 */

#if NTSJ_HAVE_U128
/* v x 2^e (v != 0), v's bits beyond 53 rounded to nearest, ties to even,
 * `sticky` when something nonzero lies below v's last bit. */
static double round_to_double(uint64_t v, int e, int sticky) {
    const int n = 64 - __builtin_clzll(v);
    uint64_t mant, bits;
    double out;
    if (n <= 53) { /* exact (nothing below it: the callers' values then have no sticky) */
        mant = v << (53 - n);
        e -= 53 - n;
    } else {
        const int shift = n - 53;
        const uint64_t rest = v & (((uint64_t)1 << shift) - 1), half = (uint64_t)1 << (shift - 1);
        mant = v >> shift;
        e += shift;
        /* up or not by arithmetic: which way a random number rounds is a
         * coin toss, the one branch no predictor guesses */
        mant += (uint64_t)((rest > half) | ((rest == half) & ((sticky != 0) | (int)(mant & 1u))));
        if (mant == (uint64_t)1 << 53) {
            mant >>= 1;
            ++e;
        }
    }
    /* mant in [2^52, 2^53): the value is 1.f x 2^(e + 52), a normal double */
    bits = (uint64_t)(e + 52 + 1023) << 52 | (mant & (((uint64_t)1 << 52) - 1));
    memcpy(&out, &bits, sizeof out);
    return out;
}

/* v x 2^e for a 128-bit v: its top 64 bits, the rest as the sticky bit. */
static double round128(u128 v, int e) {
    const uint64_t hi = (uint64_t)(v >> 64), lo = (uint64_t)v;
    int sh;
    if (hi == 0) return round_to_double(lo, e, 0);
    sh = 64 - __builtin_clzll(hi);
    return round_to_double((uint64_t)(v >> sh), e + sh, (lo & (((uint64_t)1 << sh) - 1)) != 0);
}

/* num / d when the quotient fits 64 bits (num < d 2^64): one divq where
 * there is one, rather than the 128-bit division's library call. */
static void divide(u128 num, uint64_t d, uint64_t* quot, uint64_t* rem) {
#if defined(__x86_64__) && defined(__GNUC__)
    uint64_t hi = (uint64_t)(num >> 64), lo = (uint64_t)num;
    __asm__("divq %4" : "=a"(lo), "=d"(hi) : "a"(lo), "d"(hi), "rm"(d));
    *quot = lo;
    *rem = hi;
#else
    *quot = (uint64_t)(num / d);
    *rem = (uint64_t)(num % d);
#endif
}

static const uint64_t pow5[NTSJ_FAST_EXP + 1] = {
    1ull, 5ull, 25ull, 125ull, 625ull, 3125ull, 15625ull, 78125ull, 390625ull, 1953125ull, 9765625ull,
    48828125ull, 244140625ull, 1220703125ull, 6103515625ull, 30517578125ull, 152587890625ull,
    762939453125ull, 3814697265625ull, 19073486328125ull, 95367431640625ull, 476837158203125ull,
    2384185791015625ull, 11920928955078125ull, 59604644775390625ull, 298023223876953125ull,
    1490116119384765625ull, 7450580596923828125ull};

/* w / 5^k x 2^-k (w != 0, 1 <= k <= 27) by the division: w shifted so that
 * the quotient has 63 or 64 bits (at least the 53 kept, a rounding bit and
 * more), the remainder the sticky bit. */
static double quotient(uint64_t w, int k) {
    const uint64_t d = pow5[k];
    const int s = (64 - __builtin_clzll(d)) + 63 - (64 - __builtin_clzll(w));
    uint64_t quot, rem;
    divide((u128)w << s, d, &quot, &rem);
    return round_to_double(quot, -s - k, rem != 0);
}

/* The same by one product instead of the division, whose latency was a
 * third of a JSON step's reading (docs/benchmarks.md): after Lemire's
 * "Number parsing at a gigabyte per second" (2021), with the printer's
 * multiplier M = floor(2^(z - 1 + 125) / 5^k) + 1 (z = bits(5^k)), which
 * exceeds 2^(z - 1 + 125) / 5^k by less than 1. So the product P = w' M (w'
 * = w shifted to 64 bits) exceeds the exact X = w' 2^(z - 1 + 125) / 5^k by
 * less than w' < 2^64: X / 2^64 lies within 1 of P's top 128 bits, T. When
 * the bits of T below the rounding bit, read as one number, are not all
 * zero, X has T's 53 bits and rounding bit and something nonzero below them
 * (sticky): the nearest double is decided. Otherwise the division decides:
 * 1 random number in about 2^70, and every decimal that is an exact double
 * ("0.5", and "3.0" as the printer writes an integer) or an exact tie. */
static double divided(uint64_t w, int k) {
    const int lz = __builtin_clzll(w);
    const uint64_t wn = w << lz, mlo = ntsj_pow5_inv[k][0], mhi = ntsj_pow5_inv[k][1];
    const u128 top = (u128)wn * mhi + (u128)(((u128)wn * mlo) >> 64);
    const uint64_t hi = (uint64_t)(top >> 64), lo = (uint64_t)top;
    const int shift = 11 - __builtin_clzll(hi); /* hi has 64 - clz bits: keep 53 */
    const uint64_t below = hi & (((uint64_t)1 << (shift - 1)) - 1);
    if ((below | lo) == 0) return quotient(w, k);
    /* P 2^(-lz - (bits(5^k) + 124) - k), hi its 2^128s; sticky */
    return round_to_double(hi, 4 - lz - (int)ntsj_pow5_bits((uint32_t)k) - k, 1);
}

/* w x 10^q (w != 0, |q| <= 27), the nearest double. */
static double exact(uint64_t w, int q) {
    return q >= 0 ? round128((u128)w * pow5[q], q) : divided(w, -q);
}
#endif

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
#define NTSJ_SWAR 1
/* Eight digits at once (the digit loop is a chain of multiply-adds, the
 * reader's longest part): whether the eight bytes at p are all '0'..'9':
 * each byte's high nibble 3, and no low nibble that overflows past 9 when
 * 6 is added. */
static int eight_digits(const char* p) {
    uint64_t v;
    memcpy(&v, p, sizeof v);
    return ((v & 0xF0F0F0F0F0F0F0F0ull) | (((v + 0x0606060606060606ull) & 0xF0F0F0F0F0F0F0F0ull) >> 4)) ==
           0x3333333333333333ull;
}

/* Their value: pairs of digits, then pairs of pairs, then the two halves
 * (the first byte is the most significant digit). `v` holds the digits'
 * values (each byte 0..9). */
static uint64_t eight_value_of(uint64_t v) {
    v = v * 10u + (v >> 8); /* each even byte: two digits' value */
    return ((v & 0x000000FF000000FFull) * (100u + (1000000ull << 32)) +
            ((v >> 16) & 0x000000FF000000FFull) * (1u + (10000ull << 32))) >> 32;
}

static uint64_t eight_value(const char* p) {
    uint64_t v;
    memcpy(&v, p, sizeof v);
    return eight_value_of(v - 0x3030303030303030ull);
}

/* The leading digit bytes of the eight at p (0..8): a carry of + 6 only
 * reaches bytes after a non-digit, past the first. */
static int digit_run(const char* p) {
    uint64_t v, not_digit;
    memcpy(&v, p, sizeof v);
    not_digit = ((v & 0xF0F0F0F0F0F0F0F0ull) ^ 0x3030303030303030ull) |
                (((v + 0x0606060606060606ull) & 0xF0F0F0F0F0F0F0F0ull) ^ 0x3030303030303030ull);
    return not_digit == 0 ? 8 : __builtin_ctzll(not_digit) / 8;
}

/* The value of the n digits at p (1 <= n <= 8; the eight bytes at p readable). */
static uint64_t run_value(const char* p, int n) {
    uint64_t v;
    memcpy(&v, p, sizeof v);
    return eight_value_of((v - 0x3030303030303030ull) << (8 * (8 - n)));
}

/* The last 1..7 digits (the run ends within the eight bytes at p) in one
 * step rather than a loop whose length varies: their count and their value
 * with zeros shifted in ahead of them. */
static int tail_digits(const char* p, int room, uint64_t* w) {
    static const uint64_t pow10[8] = {1u, 10u, 100u, 1000u, 10000u, 100000u, 1000000u, 10000000u};
    const int k = digit_run(p);
    if (k == 0 || k == 8 || k > room) return 0; /* (eight: the caller's loops) */
    *w = *w * pow10[k] + run_value(p, k);
    return k;
}
#else
#define NTSJ_SWAR 0
#endif

#if NTSJ_SWAR && NTSJ_HAVE_U128
/* The plain decimal a solver writes, "-?d+.d+" of at most 19 digits, its
 * integer part of 1 to 7 digits and its fraction of 1 to 15, with 40 bytes
 * readable at p: its runs measured a word at a time and their values taken
 * whole (no loop whose length follows the digits, so no branch that
 * mispredicts with a number's length). Its length, *out the nearest double;
 * 0 when it is not such a number (the general way reads it, or refuses it). */
static size_t plain_decimal(const char* p, double* out) {
    static const uint64_t pow10[16] = {1u, 10u, 100u, 1000u, 10000u, 100000u, 1000000u, 10000000u,
                                       100000000u, 1000000000u, 10000000000u, 100000000000u,
                                       1000000000000u, 10000000000000u, 100000000000000u,
                                       1000000000000000u};
    const int neg = *p == '-';
    const char* q = p + neg;
    const int whole = digit_run(q);
    const char* f = q + whole + 1;
    int frac;
    uint64_t w;
    double v;
    if (whole == 0 || whole == 8 || q[whole] != '.' || (whole > 1 && *q == '0')) return 0;
    frac = digit_run(f);
    if (frac == 8) frac += digit_run(f + 8);
    if (frac == 0 || frac == 16 || f[frac] == 'e' || f[frac] == 'E' || whole + frac > NTSJ_FAST_DIGITS) return 0;
    w = run_value(q, whole) * pow10[frac] +
        (frac <= 8 ? run_value(f, frac) : eight_value(f) * pow10[frac - 8] + run_value(f + 8, frac - 8));
    v = w == 0 ? 0.0 : exact(w, -frac);
    *out = neg ? -v : v;
    return (size_t)(f + frac - p);
}
#endif

size_t ntsj_parse_number(const char* p, const char* end, double* out) {
    const char* q = p;
    uint64_t w = 0;
    int digits = 0, many = 0, exp10 = 0, neg = 0;
#if NTSJ_SWAR && NTSJ_HAVE_U128
    if (end - p >= 40) {
        const size_t n = plain_decimal(p, out);
        if (n > 0) return n;
    }
#endif
    if (q < end && *q == '-') {
        neg = 1;
        ++q;
    }
    if (q >= end || *q < '0' || *q > '9') return 0;
    if (*q == '0') {
        ++q;
    } else {
#if NTSJ_SWAR
        w = (uint64_t)(*q++ - '0'); /* then significant: eight at a time while they fit */
        digits = 1;
        for (; digits + 8 <= NTSJ_FAST_DIGITS && end - q >= 8 && eight_digits(q); q += 8, digits += 8)
            w = w * 100000000u + eight_value(q);
        if (end - q >= 8) {
            const int k = tail_digits(q, NTSJ_FAST_DIGITS - digits, &w);
            q += k, digits += k;
        }
#endif
        for (; q < end && *q >= '0' && *q <= '9'; ++q) {
            if (digits < NTSJ_FAST_DIGITS) w = w * 10u + (uint64_t)(*q - '0'), ++digits;
            else many = 1; /* (strtod reads it) */
        }
    }
    if (q < end && *q == '.') {
        ++q;
        if (q >= end || *q < '0' || *q > '9') return 0;
#if NTSJ_SWAR
        while (w == 0 && q < end && *q == '0' && exp10 > -100000) ++q, --exp10; /* leading zeros: not significant */
        for (; digits + 8 <= NTSJ_FAST_DIGITS && end - q >= 8 && eight_digits(q); q += 8, digits += 8, exp10 -= 8)
            w = w * 100000000u + eight_value(q);
        if (end - q >= 8) {
            const int k = tail_digits(q, NTSJ_FAST_DIGITS - digits, &w);
            q += k, digits += k, exp10 -= k;
        }
#endif
        for (; q < end && *q >= '0' && *q <= '9'; ++q) {
            if (digits >= NTSJ_FAST_DIGITS || exp10 < -100000) many = 1; /* (strtod reads it) */
            else if (w == 0 && *q == '0') --exp10; /* a leading zero: not significant */
            else w = w * 10u + (uint64_t)(*q - '0'), ++digits, --exp10;
        }
    }
    if (q < end && (*q == 'e' || *q == 'E')) {
        int eneg = 0, e = 0;
        ++q;
        if (q < end && (*q == '+' || *q == '-')) eneg = *q++ == '-';
        if (q >= end || *q < '0' || *q > '9') return 0;
        for (; q < end && *q >= '0' && *q <= '9'; ++q)
            if (e < 100000) e = e * 10 + (*q - '0'); /* (beyond: strtod's) */
        if (e >= 100000) many = 1;
        exp10 += eneg ? -e : e;
    }
#if NTSJ_HAVE_U128
    if (w == 0 && !many) {
        *out = neg ? -0.0 : 0.0;
        return (size_t)(q - p);
    }
    if (!many && exp10 >= -NTSJ_FAST_EXP && exp10 <= NTSJ_FAST_EXP) {
        const double v = exact(w, exp10);
        *out = neg ? -v : v;
        return (size_t)(q - p);
    }
#endif
    {
        char buf[64];
        const size_t n = (size_t)(q - p);
        if (n >= sizeof buf) return 0; /* (the caller's general way takes it) */
        memcpy(buf, p, n);
        buf[n] = '\0';
        *out = c_strtod(buf, NULL);
        return n;
    }
}

int ntsj_parse_double(const char* text, double* out) {
    const size_t len = text != NULL ? strlen(text) : 0;
    double v = 0.0;
    if (len == 0 || ntsj_parse_number(text, text + len, &v) != len) {
        /* (64 characters or more: the reader leaves them to strtod, as
         * cJSON does, once the requests' own scan has found the text one
         * JSON value; one that starts with a digit or '-' and ends with a
         * digit, no space around it, is one number) */
        const char last = len > 0 ? text[len - 1] : '\0';
        if (len < 64 || !(*text == '-' || (*text >= '0' && *text <= '9')) || last < '0' || last > '9' ||
            ntsj_json_check(text, len, 1, NULL, 0, NULL, 0) != NULL)
            return -1;
        v = c_strtod(text, NULL);
    }
    if (!isfinite(v)) return 1;
    *out = v;
    return 0;
}
