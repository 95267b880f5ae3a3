/* The output buffer and the number printer of the codec.
 *
 * Doubles are printed as the shortest digits that read back bitwise equal
 * through strtod (Ryu's), so the JSON carries exactly the value the core
 * computed; cJSON's own printer stops at 15 digits when that
 * looks equal and is not used for numbers. The decimal point is always '.',
 * whatever the locale (and nothing here calls setlocale). */
#include <assert.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "codec_internal.h"

void ntsj_buf_init(ntsj_buf* b) {
    b->data = NULL;
    b->len = 0;
    b->cap = 0;
    b->oom = 0;
    b->max = 0;
    b->over = 0;
}

void ntsj_buf_free(ntsj_buf* b) {
    nts_free(b->data);
    ntsj_buf_init(b);
}

int ntsj_buf_reserve(ntsj_buf* b, size_t extra) {
    size_t need, cap;
    char* p;
    if (b->oom) return -1;
    if (extra > (size_t)-1 / 2 - b->len) {
        b->oom = 1;
        return -1;
    }
    need = b->len + extra + 1; /* room for the terminating NUL */
    if (need <= b->cap) return 0;
    if (b->max > 0 && need > b->max) {
        b->over = b->oom = 1;
        return -1;
    }
    cap = b->cap ? b->cap : 256;
    while (cap < need) cap *= 2;
    if (b->max > 0 && cap > b->max) cap = b->max;
    p = (char*)nts_alloc(cap);
    if (!p) {
        b->oom = 1;
        return -1;
    }
    if (b->data) memcpy(p, b->data, b->len + 1);
    else p[0] = '\0';
    nts_free(b->data);
    b->data = p;
    b->cap = cap;
    return 0;
}

void ntsj_buf_hint(ntsj_buf* b, size_t extra) {
    if (b->max > 0) {
        if (b->len + 1 >= b->max) return;
        if (extra > b->max - b->len - 1) extra = b->max - b->len - 1;
    }
    (void)ntsj_buf_reserve(b, extra);
}

void ntsj_buf_put(ntsj_buf* b, const char* s, size_t n) {
    if (ntsj_buf_reserve(b, n) != 0) return;
    memcpy(b->data + b->len, s, n);
    b->len += n;
    b->data[b->len] = '\0';
}

void ntsj_buf_puts(ntsj_buf* b, const char* s) { ntsj_buf_put(b, s, strlen(s)); }

void ntsj_buf_putc(ntsj_buf* b, char c) {
    if (ntsj_buf_reserve(b, 1) != 0) return;
    b->data[b->len++] = c;
    b->data[b->len] = '\0';
}

void ntsj_buf_int(ntsj_buf* b, long long v) {
    char tmp[32];
    int n = snprintf(tmp, sizeof tmp, "%lld", v);
    ntsj_buf_put(b, tmp, (size_t)n);
}

void ntsj_buf_string(ntsj_buf* b, const char* s) {
    static const char hex[] = "0123456789abcdef";
    const unsigned char* p = (const unsigned char*)s;
    ntsj_buf_putc(b, '"');
    for (; *p; ++p) {
        unsigned char c = *p;
        if (c == '"' || c == '\\') {
            char e[2] = {'\\', (char)c};
            ntsj_buf_put(b, e, 2);
        } else if (c < 0x20) {
            char e[6] = {'\\', 'u', '0', '0', hex[c >> 4], hex[c & 15]};
            switch (c) {
            case '\n': ntsj_buf_put(b, "\\n", 2); break;
            case '\r': ntsj_buf_put(b, "\\r", 2); break;
            case '\t': ntsj_buf_put(b, "\\t", 2); break;
            case '\b': ntsj_buf_put(b, "\\b", 2); break;
            case '\f': ntsj_buf_put(b, "\\f", 2); break;
            default: ntsj_buf_put(b, e, 6); break;
            }
        } else if (c < 0x80) {
            ntsj_buf_putc(b, (char)c);
        } else {
            /* Copy a whole UTF-8 sequence; a broken one (a message cut by
             * snprintf in the middle of a character) becomes U+FFFD. */
            size_t len = c >= 0xF0 ? 4 : c >= 0xE0 ? 3 : c >= 0xC2 ? 2 : 0, i;
            for (i = 1; i < len; ++i)
                if ((p[i] & 0xC0) != 0x80) break;
            if (len == 0 || c > 0xF4 || i < len) {
                ntsj_buf_put(b, "\\ufffd", 6);
            } else {
                ntsj_buf_put(b, (const char*)p, len);
                p += len - 1;
            }
        }
    }
    ntsj_buf_putc(b, '"');
}

/* ------------------------------------------------------------------------
 * The shortest digits (U. Adams, "Ryu: fast float-to-string conversion",
 * PLDI 2018): of the decimals that read back as v (those inside v's rounding
 * interval, its ends included when v's significand is even, as strtod's
 * ties to even take them), the one with the fewest digits, and of those the
 * nearest to v (ties to even). The interval's ends and v, times 4 and then
 * times a power of ten, are computed with one 64 x 128-bit product each
 * (numfmt_pow5.h, exact multipliers) and are exact to the digits kept; the
 * digits below are removed while the ends still differ. Whether what was
 * removed was all zeros is known only for small powers (the removal's
 * "trailing zeros"), which decides the ends and the ties. Why not Grisu2
 * (the printer before): it gave one digit more for about 1 double in 1,000,
 * and this is 1.4-1.7 times as fast on the forces a step writes
 * (docs/codec.md). tests/codec/numfmt_check.c checks millions of doubles
 * against strtod and snprintf.
 * ---------------------------------------------------------------------- */

#include "numfmt_pow5.h"

/* floor(e log10 2) for e < 1650, floor(e log10 5) for e < 2620. */
static uint32_t log10_pow2(uint32_t e) { return (e * 78913u) >> 18; }
static uint32_t log10_pow5(uint32_t e) { return (e * 732923u) >> 20; }

/* Whether 5^p divides v (v > 0). */
static int multiple_of_pow5(uint64_t v, uint32_t p) {
    uint32_t n = 0;
    while (n < p) {
        const uint64_t q = v / 5u;
        if (v != 5u * q) return 0;
        v = q;
        ++n;
    }
    return 1;
}

/* (m x mul) >> j, mul the 128-bit {low, high}, 64 <= j < 192, m < 2^56
 * (so that the result has 64 bits at most). */
#if defined(__SIZEOF_INT128__)
__extension__ typedef unsigned __int128 fmt_u128;
static uint64_t mul_shift(uint64_t m, const uint64_t* mul, int j) {
    const fmt_u128 lo = (fmt_u128)m * mul[0], hi = (fmt_u128)m * mul[1];
    return (uint64_t)(((lo >> 64) + hi) >> (j - 64));
}
#else
/* a x b = *hi 2^64 + low 64 bits, from 32-bit halves */
static uint64_t mul_64x64(uint64_t a, uint64_t b, uint64_t* hi) {
    const uint64_t a0 = a & 0xFFFFFFFFu, a1 = a >> 32, b0 = b & 0xFFFFFFFFu, b1 = b >> 32;
    const uint64_t p00 = a0 * b0, p01 = a0 * b1, p10 = a1 * b0, p11 = a1 * b1;
    const uint64_t mid = (p00 >> 32) + (p01 & 0xFFFFFFFFu) + (p10 & 0xFFFFFFFFu);
    *hi = p11 + (p01 >> 32) + (p10 >> 32) + (mid >> 32);
    return (mid << 32) | (p00 & 0xFFFFFFFFu);
}
static uint64_t mul_shift(uint64_t m, const uint64_t* mul, int j) {
    uint64_t lo_hi, hi_hi, hi_lo, sum, top;
    (void)mul_64x64(m, mul[0], &lo_hi);
    hi_lo = mul_64x64(m, mul[1], &hi_hi);
    sum = lo_hi + hi_lo;
    top = hi_hi + (sum < lo_hi); /* (lo >> 64) + hi = top 2^64 + sum */
    j -= 64;
    return j == 0 ? sum : j < 64 ? (sum >> j) | (top << (64 - j)) : top >> (j - 64);
}
#endif

/* v > 0, finite: v reads back from *digits x 10^*exp, *digits the shortest. */
static void shortest(double v, uint64_t* digits, int* exp) {
    const uint64_t frac_mask = (UINT64_C(1) << 52) - 1;
    uint64_t bits, m2, mv, vr, vp, vm;
    uint32_t ie, mm_shift, q;
    int e2, e10, accept, vm_tz = 0, vr_tz = 0, removed = 0;
    unsigned last = 0;
    memcpy(&bits, &v, sizeof bits);
    ie = (uint32_t)(bits >> 52) & 0x7FFu;
    m2 = ie == 0 ? bits & frac_mask : (UINT64_C(1) << 52) | (bits & frac_mask);
    e2 = (ie == 0 ? 1 : (int)ie) - 1023 - 52 - 2; /* v = 4 m2 x 2^e2 */
    accept = (m2 & 1u) == 0;                        /* an even significand: the interval's ends read back */
    mv = 4u * m2;
    mm_shift = (bits & frac_mask) != 0 || ie <= 1; /* 0: a power of two, its lower neighbour nearer */
    if (e2 >= 0) {
        const int k = 125 + (int)ntsj_pow5_bits(q = log10_pow2((uint32_t)e2) - (e2 > 3)) - 1, j = -e2 + (int)q + k;
        e10 = (int)q;
        vr = mul_shift(mv, ntsj_pow5_inv[q], j);
        vp = mul_shift(mv + 2u, ntsj_pow5_inv[q], j);
        vm = mul_shift(mv - 1u - mm_shift, ntsj_pow5_inv[q], j);
        if (q <= 21) { /* 5^q may divide an end or v: the digits removed may be exact zeros */
            if (mv % 5u == 0) vr_tz = multiple_of_pow5(mv, q);
            else if (accept) vm_tz = multiple_of_pow5(mv - 1u - mm_shift, q);
            else vp -= (uint64_t)multiple_of_pow5(mv + 2u, q); /* the upper end excluded */
        }
    } else {
        const uint32_t i = (uint32_t)-e2 - (q = log10_pow5((uint32_t)-e2) - (-e2 > 1));
        const int j = (int)q - ((int)ntsj_pow5_bits(i) - 125);
        e10 = (int)q + e2;
        vr = mul_shift(mv, pow5[i], j);
        vp = mul_shift(mv + 2u, pow5[i], j);
        vm = mul_shift(mv - 1u - mm_shift, pow5[i], j);
        if (q <= 1) {
            vr_tz = 1; /* mv x 2^-q: no digit below */
            if (accept) vm_tz = mm_shift == 1;
            else --vp;
        } else if (q < 63) {
            vr_tz = (mv & ((UINT64_C(1) << q) - 1)) == 0; /* 2^q divides mv */
        }
    }
    if (vm_tz || vr_tz) { /* (rare: exact ends or an exact v) */
        while (vm > 0 && vp / 10000u > vm / 10000u) { /* four digits a step, as four of the loop below */
            const uint64_t r = vr % 10000u;
            vm_tz &= vm % 10000u == 0;
            vr_tz &= last == 0 && r % 1000u == 0;
            last = (unsigned)(r / 1000u);
            vr /= 10000u, vp /= 10000u, vm /= 10000u;
            removed += 4;
        }
        while (vm > 0 && vp / 10u > vm / 10u) {
            vm_tz &= vm % 10u == 0;
            vr_tz &= last == 0;
            last = (unsigned)(vr % 10u);
            vr /= 10u, vp /= 10u, vm /= 10u;
            ++removed;
        }
        while (vm_tz && vm > 0 && vm % 10u == 0) { /* the lower end's own zeros: it reads back */
            vr_tz &= last == 0;
            last = (unsigned)(vr % 10u);
            vr /= 10u, vp /= 10u, vm /= 10u;
            ++removed;
        }
        if (vr_tz && last == 5 && vr % 2u == 0) last = 4; /* an exact tie: to even */
        *digits = vr + (unsigned)((vr == vm && (!accept || !vm_tz)) || last >= 5);
    } else {
        int up = 0;
        while (vp / 10000u > vm / 10000u) { /* (short numbers: four digits a step) */
            up = vr % 10000u >= 5000u;
            vr /= 10000u, vp /= 10000u, vm /= 10000u;
            removed += 4;
        }
        while (vp / 10u > vm / 10u) {
            up = vr % 10u >= 5u;
            vr /= 10u, vp /= 10u, vm /= 10u;
            ++removed;
        }
        *digits = vr + (unsigned)(vr == vm || up);
    }
    *exp = e10 + removed;
}

static const char two_digits[201] = "00010203040506070809101112131415161718192021222324"
                                    "25262728293031323334353637383940414243444546474849"
                                    "50515253545556575859606162636465666768697071727374"
                                    "75767778798081828384858687888990919293949596979899";

/* The number of decimal digits of v (v < 10^19). */
static int decimal_length(uint64_t v) {
    static const uint64_t pow10[20] = {
        UINT64_C(1), UINT64_C(10), UINT64_C(100), UINT64_C(1000), UINT64_C(10000), UINT64_C(100000),
        UINT64_C(1000000), UINT64_C(10000000), UINT64_C(100000000), UINT64_C(1000000000),
        UINT64_C(10000000000), UINT64_C(100000000000), UINT64_C(1000000000000), UINT64_C(10000000000000),
        UINT64_C(100000000000000), UINT64_C(1000000000000000), UINT64_C(10000000000000000),
        UINT64_C(100000000000000000), UINT64_C(1000000000000000000), UINT64_C(10000000000000000000)};
    const int t = ((64 - __builtin_clzll(v | 1u)) * 1233) >> 12; /* floor(bits x log10 2): the length or one less */
    return t + (v >= pow10[t]);
}

/* Four digits of v < 10^4 at p, from the table of pairs. */
static void write4(char* p, uint32_t v) {
    const uint32_t hi = v / 100u;
    memcpy(p, two_digits + 2 * hi, 2);
    memcpy(p + 2, two_digits + 2 * (v - 100u * hi), 2);
}

/* v < 10^17 as 17 digits at p, leading zeros and all: the same steps
 * whatever v's length (a loop that runs as many times as v has digits
 * mispredicts with the length of a random double). */
static void write17(char* p, uint64_t v) {
    const uint64_t top = v / 100000000u;
    const uint32_t lo = (uint32_t)(v - 100000000u * top), mid = (uint32_t)(top % 100000000u);
    p[0] = (char)('0' + (unsigned)(top / 100000000u));
    write4(p + 1, mid / 10000u);
    write4(p + 5, mid % 10000u);
    write4(p + 9, lo / 10000u);
    write4(p + 13, lo % 10000u);
}

int ntsj_format_double(char* out, double v) {
    /* z: '0's, the 17 digits at z + 8 (leading zeros included); t: the text
     * before it is copied out */
    char z[72], t[48];
    const char* digits;
    int len = 0, K = 0, k, n = 0;
    if (!isfinite(v)) {
        memcpy(out, "null", 5);
        return 4;
    }
    out[0] = '-'; /* kept by the sign bit: the forces' signs are a coin toss, no branch guesses them */
    n = signbit(v) != 0;
    v = fabs(v);
    if (v == 0.0) {
        memcpy(out + n, "0.0", 4); /* keeps the sign of zero: "-0.0" reads back as -0.0 */
        return n + 3;
    }
    {
        uint64_t d;
        shortest(v, &d, &K);
        assert(d < UINT64_C(100000000000000000)); /* at most 17 digits (a double needs no more) */
        len = decimal_length(d);
        memset(z, '0', sizeof z);
        write17(z + 8, d);
        digits = z + 25 - len;
    }
    k = len + K; /* v = 0.d1d2... x 10^k */
    if (k > -5 && k <= 17) {
        /* 0.000ddd, dd.ddd or ddd000.0 by the same steps (which of the three
         * a force takes follows its magnitude, a branch no predictor
         * guesses): the digits with P = max(1 - k, 0) zeros before them and
         * '0's after, its first ip = max(k, 1) characters, a '.', then the
         * rest up to the last digit or the '0' after the '.'. Copies of
         * fixed sizes (the bytes past the text are overwritten or left
         * beyond its NUL, within the 32 that out holds: the text has 23
         * characters at most). */
        const int P = k < 1 ? 1 - k : 0, ip = k > 1 ? k : 1, last = len + P > ip + 1 ? len + P : ip + 1;
        const char* from = digits - P;
        memcpy(t, from, 24);
        memcpy(t + ip + 1, from + ip, 30); /* (t's first 31 all written) */
        t[ip] = '.';
        memcpy(out + n, t, 31);
        n += last + 1;
    } else { /* d.ddde+XX, as printf writes exponents */
        int e = k - 1;
        out[n++] = digits[0];
        if (len > 1) {
            out[n++] = '.';
            memcpy(out + n, digits + 1, (size_t)(len - 1));
            n += len - 1;
        }
        out[n++] = 'e';
        out[n++] = e < 0 ? '-' : '+';
        if (e < 0) e = -e;
        if (e >= 100) {
            out[n++] = (char)('0' + e / 100);
            e %= 100;
            out[n++] = (char)('0' + e / 10);
        } else {
            out[n++] = (char)('0' + e / 10);
        }
        out[n++] = (char)('0' + e % 10);
    }
    out[n] = '\0';
    return n;
}

void ntsj_buf_double(ntsj_buf* b, double v) {
    char tmp[NTSJ_DOUBLE_MAX];
    int n;
    if (!b->oom && b->data != NULL && b->len + NTSJ_DOUBLE_MAX < b->cap) { /* in place while there is room */
        b->len += (size_t)ntsj_format_double(b->data + b->len, v);
        return;
    }
    n = ntsj_format_double(tmp, v);
    ntsj_buf_put(b, tmp, (size_t)n);
}
