/* The output buffer and the number printer of the codec.
 *
 * Doubles are printed with Grisu2: digits that read back bitwise equal through
 * strtod (almost always the shortest such), so the JSON carries exactly the
 * value the core computed; cJSON's own printer stops at 15 digits when that
 * looks equal and is not used for numbers. The decimal point is always '.',
 * whatever the locale (and nothing here calls setlocale). */
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
 * Grisu2 (F. Loitsch, "Printing floating-point numbers quickly and accurately
 * with integers", PLDI 2010; the layout follows Milo Yip's dtoa): digits of a
 * double that read back bitwise equal, almost always the shortest, with 64-bit
 * integer arithmetic only. glibc's snprintf("%.17g") costs ~0.5 us a number;
 * this ~0.05 us. tests/numfmt_check.c checks millions of doubles against strtod.
 * ---------------------------------------------------------------------- */

typedef struct diy_fp {
    uint64_t f;
    int e;
} diy_fp;

#define DP_SIGNIFICAND_MASK UINT64_C(0x000FFFFFFFFFFFFF)
#define DP_EXPONENT_MASK UINT64_C(0x7FF0000000000000)
#define DP_HIDDEN_BIT UINT64_C(0x0010000000000000)
#define DP_SIGNIFICAND_SIZE 52
#define DP_EXPONENT_BIAS (0x3FF + DP_SIGNIFICAND_SIZE)
#define DIY_SIGNIFICAND_SIZE 64

static diy_fp diy_from_double(double d) {
    uint64_t bits;
    diy_fp r;
    int biased_e;
    memcpy(&bits, &d, sizeof bits);
    biased_e = (int)((bits & DP_EXPONENT_MASK) >> DP_SIGNIFICAND_SIZE);
    r.f = bits & DP_SIGNIFICAND_MASK;
    if (biased_e != 0) {
        r.f += DP_HIDDEN_BIT;
        r.e = biased_e - DP_EXPONENT_BIAS;
    } else {
        r.e = 1 - DP_EXPONENT_BIAS; /* subnormal */
    }
    return r;
}

static diy_fp diy_mul(diy_fp x, diy_fp y) {
    /* The upper 64 bits of the 128-bit product, rounded. */
    const uint64_t m32 = UINT64_C(0xFFFFFFFF);
    uint64_t a = x.f >> 32, b = x.f & m32, c = y.f >> 32, d = y.f & m32;
    uint64_t ac = a * c, bc = b * c, ad = a * d, bd = b * d;
    uint64_t tmp = (bd >> 32) + (ad & m32) + (bc & m32);
    diy_fp r;
    tmp += UINT64_C(1) << 31;
    r.f = ac + (ad >> 32) + (bc >> 32) + (tmp >> 32);
    r.e = x.e + y.e + 64;
    return r;
}

static diy_fp diy_normalize(diy_fp x) {
    while (!(x.f & (UINT64_C(1) << 63))) {
        x.f <<= 1;
        x.e--;
    }
    return x;
}

/* The boundaries m- and m+ halfway to the neighbouring doubles, with m+ normalised
 * and m- at the same exponent. */
static void diy_boundaries(diy_fp v, diy_fp* minus, diy_fp* plus) {
    diy_fp pl, mi;
    pl.f = (v.f << 1) + 1;
    pl.e = v.e - 1;
    while (!(pl.f & (DP_HIDDEN_BIT << 1))) {
        pl.f <<= 1;
        pl.e--;
    }
    pl.f <<= DIY_SIGNIFICAND_SIZE - DP_SIGNIFICAND_SIZE - 2;
    pl.e -= DIY_SIGNIFICAND_SIZE - DP_SIGNIFICAND_SIZE - 2;
    if (v.f == DP_HIDDEN_BIT) { /* the lower neighbour is closer at a power of two */
        mi.f = (v.f << 2) - 1;
        mi.e = v.e - 2;
    } else {
        mi.f = (v.f << 1) - 1;
        mi.e = v.e - 1;
    }
    mi.f <<= mi.e - pl.e;
    mi.e = pl.e;
    *plus = pl;
    *minus = mi;
}

/* 10^(-348 + 8 i) = cached_f[i] * 2^cached_e[i], i = 0..86 (generated with exact
 * integer arithmetic, significands rounded to nearest). */
static const uint64_t cached_f[87] = {
    UINT64_C(0xfa8fd5a0081c0288), UINT64_C(0xbaaee17fa23ebf76), UINT64_C(0x8b16fb203055ac76),
    UINT64_C(0xcf42894a5dce35ea), UINT64_C(0x9a6bb0aa55653b2d), UINT64_C(0xe61acf033d1a45df),
    UINT64_C(0xab70fe17c79ac6ca), UINT64_C(0xff77b1fcbebcdc4f), UINT64_C(0xbe5691ef416bd60c),
    UINT64_C(0x8dd01fad907ffc3c), UINT64_C(0xd3515c2831559a83), UINT64_C(0x9d71ac8fada6c9b5),
    UINT64_C(0xea9c227723ee8bcb), UINT64_C(0xaecc49914078536d), UINT64_C(0x823c12795db6ce57),
    UINT64_C(0xc21094364dfb5637), UINT64_C(0x9096ea6f3848984f), UINT64_C(0xd77485cb25823ac7),
    UINT64_C(0xa086cfcd97bf97f4), UINT64_C(0xef340a98172aace5), UINT64_C(0xb23867fb2a35b28e),
    UINT64_C(0x84c8d4dfd2c63f3b), UINT64_C(0xc5dd44271ad3cdba), UINT64_C(0x936b9fcebb25c996),
    UINT64_C(0xdbac6c247d62a584), UINT64_C(0xa3ab66580d5fdaf6), UINT64_C(0xf3e2f893dec3f126),
    UINT64_C(0xb5b5ada8aaff80b8), UINT64_C(0x87625f056c7c4a8b), UINT64_C(0xc9bcff6034c13053),
    UINT64_C(0x964e858c91ba2655), UINT64_C(0xdff9772470297ebd), UINT64_C(0xa6dfbd9fb8e5b88f),
    UINT64_C(0xf8a95fcf88747d94), UINT64_C(0xb94470938fa89bcf), UINT64_C(0x8a08f0f8bf0f156b),
    UINT64_C(0xcdb02555653131b6), UINT64_C(0x993fe2c6d07b7fac), UINT64_C(0xe45c10c42a2b3b06),
    UINT64_C(0xaa242499697392d3), UINT64_C(0xfd87b5f28300ca0e), UINT64_C(0xbce5086492111aeb),
    UINT64_C(0x8cbccc096f5088cc), UINT64_C(0xd1b71758e219652c), UINT64_C(0x9c40000000000000),
    UINT64_C(0xe8d4a51000000000), UINT64_C(0xad78ebc5ac620000), UINT64_C(0x813f3978f8940984),
    UINT64_C(0xc097ce7bc90715b3), UINT64_C(0x8f7e32ce7bea5c70), UINT64_C(0xd5d238a4abe98068),
    UINT64_C(0x9f4f2726179a2245), UINT64_C(0xed63a231d4c4fb27), UINT64_C(0xb0de65388cc8ada8),
    UINT64_C(0x83c7088e1aab65db), UINT64_C(0xc45d1df942711d9a), UINT64_C(0x924d692ca61be758),
    UINT64_C(0xda01ee641a708dea), UINT64_C(0xa26da3999aef774a), UINT64_C(0xf209787bb47d6b85),
    UINT64_C(0xb454e4a179dd1877), UINT64_C(0x865b86925b9bc5c2), UINT64_C(0xc83553c5c8965d3d),
    UINT64_C(0x952ab45cfa97a0b3), UINT64_C(0xde469fbd99a05fe3), UINT64_C(0xa59bc234db398c25),
    UINT64_C(0xf6c69a72a3989f5c), UINT64_C(0xb7dcbf5354e9bece), UINT64_C(0x88fcf317f22241e2),
    UINT64_C(0xcc20ce9bd35c78a5), UINT64_C(0x98165af37b2153df), UINT64_C(0xe2a0b5dc971f303a),
    UINT64_C(0xa8d9d1535ce3b396), UINT64_C(0xfb9b7cd9a4a7443c), UINT64_C(0xbb764c4ca7a44410),
    UINT64_C(0x8bab8eefb6409c1a), UINT64_C(0xd01fef10a657842c), UINT64_C(0x9b10a4e5e9913129),
    UINT64_C(0xe7109bfba19c0c9d), UINT64_C(0xac2820d9623bf429), UINT64_C(0x80444b5e7aa7cf85),
    UINT64_C(0xbf21e44003acdd2d), UINT64_C(0x8e679c2f5e44ff8f), UINT64_C(0xd433179d9c8cb841),
    UINT64_C(0x9e19db92b4e31ba9), UINT64_C(0xeb96bf6ebadf77d9), UINT64_C(0xaf87023b9bf0ee6b),
};
static const int16_t cached_e[87] = {
    -1220, -1193, -1166, -1140, -1113, -1087, -1060, -1034, -1007, -980, -954, -927,
    -901, -874, -847, -821, -794, -768, -741, -715, -688, -661, -635, -608,
    -582, -555, -529, -502, -475, -449, -422, -396, -369, -343, -316, -289,
    -263, -236, -210, -183, -157, -130, -103, -77, -50, -24, 3, 30,
    56, 83, 109, 136, 162, 189, 216, 242, 269, 295, 322, 348,
    375, 402, 428, 455, 481, 508, 534, 561, 588, 614, 641, 667,
    694, 720, 747, 774, 800, 827, 853, 880, 907, 933, 960, 986,
    1013, 1039, 1066,
};

/* A cached power c = 10^-K with the product's binary exponent in [-60, -32]. */
static diy_fp cached_power(int e, int* K) {
    double dk = (-61 - e) * 0.30102999566398114 + 347; /* dk must be positive */
    int k = (int)dk;
    unsigned index;
    diy_fp r;
    if (dk - k > 0.0) k++;
    index = (unsigned)((k >> 3) + 1);
    *K = -(-348 + (int)(index << 3));
    r.f = cached_f[index];
    r.e = cached_e[index];
    return r;
}

static void grisu_round(char* buf, int len, uint64_t delta, uint64_t rest, uint64_t ten_kappa, uint64_t wp_w) {
    while (rest < wp_w && delta - rest >= ten_kappa &&
           (rest + ten_kappa < wp_w || wp_w - rest > rest + ten_kappa - wp_w)) {
        buf[len - 1]--;
        rest += ten_kappa;
    }
}

static int count_digits32(uint32_t n) {
    int d = 1;
    while (n >= 10) {
        n /= 10;
        ++d;
    }
    return d;
}

static void digit_gen(diy_fp W, diy_fp Mp, uint64_t delta, char* buf, int* len, int* K) {
    static const uint32_t pow10[] = {1, 10, 100, 1000, 10000, 100000, 1000000, 10000000, 100000000, 1000000000};
    static const uint64_t pow10_64[20] = {
        UINT64_C(1), UINT64_C(10), UINT64_C(100), UINT64_C(1000), UINT64_C(10000), UINT64_C(100000),
        UINT64_C(1000000), UINT64_C(10000000), UINT64_C(100000000), UINT64_C(1000000000),
        UINT64_C(10000000000), UINT64_C(100000000000), UINT64_C(1000000000000), UINT64_C(10000000000000),
        UINT64_C(100000000000000), UINT64_C(1000000000000000), UINT64_C(10000000000000000),
        UINT64_C(100000000000000000), UINT64_C(1000000000000000000), UINT64_C(10000000000000000000)};
    const int shift = -Mp.e;
    const uint64_t one_f = UINT64_C(1) << shift;
    const uint64_t wp_w = Mp.f - W.f;
    uint32_t p1 = (uint32_t)(Mp.f >> shift);
    uint64_t p2 = Mp.f & (one_f - 1);
    int kappa = count_digits32(p1);
    *len = 0;
    while (kappa > 0) {
        uint32_t d = p1 / pow10[kappa - 1];
        uint64_t tmp;
        p1 %= pow10[kappa - 1];
        if (d || *len) buf[(*len)++] = (char)('0' + d);
        kappa--;
        tmp = ((uint64_t)p1 << shift) + p2;
        if (tmp <= delta) {
            *K += kappa;
            grisu_round(buf, *len, delta, tmp, (uint64_t)pow10[kappa] << shift, wp_w);
            return;
        }
    }
    for (;;) { /* kappa <= 0 */
        char d;
        p2 *= 10;
        delta *= 10;
        d = (char)(p2 >> shift);
        if (d || *len) buf[(*len)++] = (char)('0' + d);
        p2 &= one_f - 1;
        kappa--;
        if (p2 < delta) {
            int index = -kappa;
            *K += kappa;
            grisu_round(buf, *len, delta, p2, one_f, index < 20 ? wp_w * pow10_64[index] : 0);
            return;
        }
    }
}

/* Digits of v > 0 (finite) in buf (at most 17), v = digits * 10^K. */
static void grisu2(double v, char* buf, int* len, int* K) {
    diy_fp w = diy_from_double(v), wm, wp, c, W, Wp, Wm;
    diy_boundaries(w, &wm, &wp);
    c = cached_power(wp.e, K);
    W = diy_mul(diy_normalize(w), c);
    Wp = diy_mul(wp, c);
    Wm = diy_mul(wm, c);
    Wm.f++;
    Wp.f--;
    digit_gen(W, Wp, Wp.f - Wm.f, buf, len, K);
}

int ntsj_format_double(char* out, double v) {
    char digits[24];
    int len = 0, K = 0, k, n = 0, i;
    if (!isfinite(v)) {
        memcpy(out, "null", 5);
        return 4;
    }
    if (signbit(v)) {
        out[n++] = '-';
        v = -v;
    }
    if (v == 0.0) {
        memcpy(out + n, "0.0", 4); /* keeps the sign of zero: "-0.0" reads back as -0.0 */
        return n + 3;
    }
    grisu2(v, digits, &len, &K);
    k = len + K; /* v = 0.d1d2... x 10^k */
    if (k > -5 && k <= 17) {
        if (k <= 0) { /* 0.000ddd */
            out[n++] = '0';
            out[n++] = '.';
            for (i = 0; i < -k; ++i) out[n++] = '0';
            memcpy(out + n, digits, (size_t)len);
            n += len;
        } else if (k >= len) { /* ddd000.0 */
            memcpy(out + n, digits, (size_t)len);
            n += len;
            for (i = len; i < k; ++i) out[n++] = '0';
            out[n++] = '.';
            out[n++] = '0';
        } else { /* dd.ddd */
            memcpy(out + n, digits, (size_t)k);
            n += k;
            out[n++] = '.';
            memcpy(out + n, digits + k, (size_t)(len - k));
            n += len - k;
        }
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
