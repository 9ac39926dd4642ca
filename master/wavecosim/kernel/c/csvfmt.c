/* CSV rows as Python writes them: every double as repr() does (the shortest decimal that reads
 * back to the same bits, the closest such one, ties to an even last digit, in repr's layout), whole
 * columns as integers or as labels. Used by wavecosim/run/recorder.py through ctypes on a
 * block of rows at a time. One route makes the digits, Schubfach's method (below), exact for every
 * double: tests/kernel/test_csvtext.py and scripts/csvfmt_check.py check it against repr.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "csvfmt.h"

typedef unsigned __int128 u128;

/* floor(x log10 2) for |x| < 1700. */
static int floor_log10_pow2(int x)
{
    return (int)(((int64_t)x * 78913) >> 18);
}

/* Schubfach's method (after Giulietti): with v = c 2^q and k = floor(log10 of the interval's
 * width), the interval's ends and centre times 4 10^-k are each one 64 x 128-bit product with a table
 * entry g, 10^-k normalized to 128 bits (exact for 10^0 .. 10^55, else rounded up: the product is then
 * above the true value by less than 2^-6 of its fraction's top word, so a top word of 0 or 1 means an
 * exact product). At most one multiple of 10^(k+1) lies in the interval; if none, the digits are
 * floor(v 10^-k) or the next integer, whichever is inside, else the closer (ties to even). */
#define POW10_MIN (-292)             /* 10^-k for k = floor(q log10 2), q from 971 down to -1074 */
#define POW10_MAX 324
#define POW5_LIMBS 14                /* 5^324 < 2^753 */

static u128 pow10_split[POW10_MAX - POW10_MIN + 1];

/* The 128 bits of x (limbs, least significant first) from bit `at` up. */
static u128 bits_from(const uint64_t *x, int at)
{
    u128 r = 0;
    for (int b = 127; b >= 0; b--) {
        int i = at + b;
        r = (r << 1) | (u128)(i >= 0 ? (x[i >> 6] >> (i & 63)) & 1u : 0u);
    }
    return r;
}

static int limbs_less(const uint64_t *a, const uint64_t *b)
{
    for (int i = POW5_LIMBS - 1; i >= 0; i--)
        if (a[i] != b[i])
            return a[i] < b[i];
    return 0;
}

static int bit_length(const uint64_t *x)
{
    int i = POW5_LIMBS - 1;
    while (!x[i])
        i--;
    return 64 * i + 64 - __builtin_clzll(x[i]);
}

/* floor(2^(bits + 127) / p) for p of `bits` bits, by binary long division from the remainder 2^(bits - 1). */
static u128 reciprocal(const uint64_t *p, int bits)
{
    uint64_t r[POW5_LIMBS] = {0};
    u128 q = 0;
    r[(bits - 1) >> 6] = UINT64_C(1) << ((bits - 1) & 63);
    for (int s = 0; s < 128; s++) {
        for (int l = POW5_LIMBS - 1; l > 0; l--)
            r[l] = (r[l] << 1) | (r[l - 1] >> 63);
        r[0] <<= 1;
        q <<= 1;
        if (!limbs_less(r, p)) {
            uint64_t borrow = 0;
            for (int l = 0; l < POW5_LIMBS; l++) {
                u128 d = (u128)r[l] - p[l] - borrow;
                r[l] = (uint64_t)d;
                borrow = (uint64_t)(d >> 64) & 1u;
            }
            q |= 1;
        }
    }
    return q;
}

/* 10^i = 5^i 2^i: the top 128 bits of 5^i (plus 1 when bits are cut off); 10^-i: 2^(bits + 127) / 5^i,
 * plus 1 (never exact for i > 0). */
static void pow10_table(void)
{
    uint64_t p[POW5_LIMBS] = {1};
    for (int i = 0; i <= POW10_MAX; i++) {
        int bits = bit_length(p);
        pow10_split[i - POW10_MIN] = bits_from(p, bits - 128) + (bits > 128);
        if (i > 0 && -i >= POW10_MIN)
            pow10_split[-i - POW10_MIN] = reciprocal(p, bits) + 1;
        uint64_t carry = 0;
        for (int l = 0; l < POW5_LIMBS; l++) {
            u128 t = (u128)p[l] * 5u + carry;
            p[l] = (uint64_t)t;
            carry = (uint64_t)(t >> 64);
        }
    }
}

static int ready = 0;

/* The table of 10^k and 10^-k; called once before any formatting. */
void csv_init(void)
{
    if (ready)
        return;
    pow10_table();
    ready = 1;
}

/* floor(g cp / 2^128), with the lowest bit set when the product is not an integer (round to odd; a
 * fraction's top word of 0 or 1 counts as zero, see above). */
static inline uint64_t round_to_odd(u128 g, uint64_t cp)
{
    u128 top = ((u128)(uint64_t)g * cp >> 64) + (u128)(uint64_t)(g >> 64) * cp;
    return (uint64_t)(top >> 64) | ((uint64_t)top > 1);
}

/* d / 10^n into *d when 10^n divides it (n = 1, 2, 4, 8): d 5^-n mod 2^64 rotated right by n is then
 * the quotient, at most (2^64 - 1) / 10^n, and otherwise larger. */
static inline int divide_out(uint64_t *d, int n)
{
    static const uint64_t INV5[9] = {0, UINT64_C(0xcccccccccccccccd), UINT64_C(0x8f5c28f5c28f5c29), 0,
                                     UINT64_C(0xd288ce703afb7e91), 0, 0, 0, UINT64_C(0xc767074b22e90e21)};
    static const uint64_t LIMIT[9] = {0, UINT64_MAX / 10, UINT64_MAX / 100, 0, UINT64_MAX / 10000, 0, 0, 0,
                                      UINT64_MAX / 100000000};
    uint64_t r = *d * INV5[n];
    r = r >> n | r << (64 - n);
    if (r > LIMIT[n])
        return 0;
    *d = r;
    return 1;
}

/* d without its trailing zeros, *k counting them. */
static inline uint64_t drop_zeros(uint64_t d, int *k)
{
    if (!divide_out(&d, 1))
        return d;
    for (++*k; divide_out(&d, 8);)
        *k += 8;
    for (int n = 4; n; n >>= 1)
        *k += n * divide_out(&d, n);
    return d;
}

/* Shortest round-trip digits of a positive finite v = m2 2^(e2 + 2) (m2 < 2^53; below a power of two
 * the lower neighbour is half as far: asym) as an integer and the decimal exponent of its last digit. */
static inline __attribute__((always_inline)) uint64_t shortest(uint64_t m2, int e2, int asym, int *dexp)
{
    int q = e2 + 2, k = asym ? (q * 1262611 - 524031) >> 22 : floor_log10_pow2(q);   /* log10 of 3/4 2^q */
    int h = q + ((-k * 1741647) >> 19) + 1;           /* floor(-k log2 10): 1 .. 4 (checked for every q) */
    u128 g = pow10_split[-k - POW10_MIN];
    uint64_t out = m2 & 1, cb = m2 << 2;                   /* ends included for an even m2 */
    uint64_t vb = round_to_odd(g, cb << h);
    uint64_t vbl = round_to_odd(g, (cb - 2 + (uint64_t)asym) << h) + out;
    uint64_t vbr = round_to_odd(g, (cb + 2) << h) - out;
    uint64_t s = vb >> 2, s10 = s / 10;
    int upin = vbl <= 40 * s10, wpin = 40 * s10 + 40 <= vbr;
    if (upin != wpin) {
        *dexp = k + 1;
        return drop_zeros(s10 + wpin, dexp);
    }
    *dexp = k;
    int uin = vbl <= s << 2, win = (s + 1) << 2 <= vbr;
    if (uin != win)
        return s + win;
    int64_t cmp = (int64_t)(vb - (4 * s + 2));
    return s + (cmp > 0 || (cmp == 0 && (s & 1)));
}

static const char DIGIT_PAIRS[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

static const uint64_t POW10[20] = {
    UINT64_C(1), UINT64_C(10), UINT64_C(100), UINT64_C(1000), UINT64_C(10000), UINT64_C(100000),
    UINT64_C(1000000), UINT64_C(10000000), UINT64_C(100000000), UINT64_C(1000000000),
    UINT64_C(10000000000), UINT64_C(100000000000), UINT64_C(1000000000000), UINT64_C(10000000000000),
    UINT64_C(100000000000000), UINT64_C(1000000000000000), UINT64_C(10000000000000000),
    UINT64_C(100000000000000000), UINT64_C(1000000000000000000), UINT64_C(10000000000000000000)};

/* How many decimal digits d has (1 for 0): log10 from the bit length, corrected by one comparison. */
static inline int digit_count(uint64_t d)
{
    int t = ((64 - __builtin_clzll(d | 1)) * 1233) >> 12;
    return t + (d >= POW10[t]) + !d;
}

/* x < 10^8 as exactly 8 ASCII digits (leading zeros), the first in the lowest byte: split in two
 * lanes of 4 digits, four of 2, eight of 1, each lane's /100 and /10 as a multiply and shift. */
static inline uint64_t digits8(uint32_t x)
{
    uint64_t v = x / 10000 | (uint64_t)(x % 10000) << 32;
    uint64_t high = ((v * 10486) >> 20) & UINT64_C(0x0000007F0000007F);
    v = high | (v - high * 100) << 16;
    high = ((v * 103) >> 10) & UINT64_C(0x000F000F000F000F);
    v = high | (v - high * 10) << 8;
    return v | UINT64_C(0x3030303030303030);
}

static inline void write8(uint32_t x, char *o)
{
    uint64_t v = digits8(x);
    memcpy(o, &v, 8);
}

/* The 24 digits of d (any uint64_t: below 10^20), with leading zeros, at o[0 .. 23]. */
static inline void write24(uint64_t d, char *o)
{
    uint64_t high = d / 100000000;
    write8((uint32_t)(high / 100000000), o);
    write8((uint32_t)(high % 100000000), o + 8);
    write8((uint32_t)(d % 100000000), o + 16);
}

/* The decimal digits of d (no leading zeros) into out; returns how many. */
static int write_digits(uint64_t d, char *out)
{
    char all[24];
    int n = digit_count(d);
    write24(d, all);
    memcpy(out, all + 24 - n, (size_t)n);
    return n;
}

/* The 16 digits of x < 10^16 as two words of 8 (digits8), the first in w[0]. */
static inline void digits16_words(uint64_t x, uint64_t w[2])
{
    uint64_t u = x / 100000000;
    w[0] = digits8((uint32_t)u);
    w[1] = digits8((uint32_t)(x - u * 100000000));
}

/* The n <= 17 digits of d at o, with a '.' after the first `point` of them when 0 < point < n;
 * returns the characters written. d is scaled to exactly 17 digits and stored in words: the first
 * digit, the other 16, then (with a point) the part after it again one byte further on, so 33 bytes
 * from o may be written whatever its length (out has that slack; what lies past the text is
 * overwritten by what follows it). */
static inline int put_digits(uint64_t d, int n, int point, char *o)
{
    const uint64_t e16 = UINT64_C(10000000000000000);
    uint64_t d17 = d * POW10[17 - n], top = d17 / e16, w[2];
    digits16_words(d17 - top * e16, w);
    o[0] = (char)('0' + top);
    memcpy(o + 1, w, 16);
    if (point <= 0 || point >= n)
        return n;
    u128 t = (u128)w[0] | (u128)w[1] << 64;
    t >>= 8 * (point - 1);
    memcpy(o + point + 1, &t, 16);
    o[point] = '.';
    return n + 1;
}

/* repr's layout of the n digits of d with value 0.d1..dn 10^decpt: exponent form when decpt - 1 < -4
 * or >= 16 (e-05, e+16), else fixed with ".0" after integral values. */
static int layout(uint64_t d, int n, int decpt, char *out)
{
    char *o = out;
    int x = decpt - 1;
    if (x < -4 || x >= 16) {
        o += put_digits(d, n, 1, o);
        *o++ = 'e';
        *o++ = x < 0 ? '-' : '+';
        int ax = x < 0 ? -x : x;
        if (ax >= 100)
            *o++ = (char)('0' + ax / 100);
        memcpy(o, DIGIT_PAIRS + 2 * (ax % 100), 2);
        o += 2;
    } else if (decpt <= 0) {
        memcpy(o, "0.000000", 8);
        o += 2 - decpt;
        o += put_digits(d, n, 0, o);
    } else if (decpt >= n) {
        o += put_digits(d, n, 0, o);
        memcpy(o, "0000000000000000", 16);
        o += decpt - n;
        memcpy(o, ".0", 2);
        o += 2;
    } else {
        o += put_digits(d, n, decpt, o);
    }
    return (int)(o - out);
}

/* repr(v) into out (at most 25 characters); returns the length. */
int csv_repr(double v, char *out)
{
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    int neg = (int)(bits >> 63), be = (int)((bits >> 52) & 0x7ff);
    uint64_t frac = bits & ((UINT64_C(1) << 52) - 1);
    char *o = out;
    *o = '-';                        /* without a branch: signs of data are as good as random */
    o += neg;
    if ((bits << 1) - 1 >= (UINT64_C(0x7ff) << 53) - 1) {     /* zero, inf or nan: one test for the three */
        if (be == 0x7ff && frac) {
            memcpy(out, "nan", 3);
            return 3;
        }
        memcpy(o, be ? "inf" : "0.0", 3);
        return (int)(o - out) + 3;
    }
    uint64_t m = be ? frac | (UINT64_C(1) << 52) : frac;
    int e = (be ? be : 1) - 1075, asym = frac == 0 && be > 1, dexp = 0;
    uint64_t d = shortest(m, e - 2, asym, &dexp);
    int n = d >= UINT64_C(1000000000000000) ? 16 + (d >= UINT64_C(10000000000000000)) : digit_count(d);
    return (int)(o - out) + layout(d, n, n + dexp, o);
}

/* v[0 .. n-1], one repr a line ending in \n (for the checks against Python's repr); out must hold
 * n * 26 characters and 64 bytes. */
long csv_lines(const double *v, long n, char *out)
{
    char *o = out;
    for (long i = 0; i < n; i++) {
        o += csv_repr(v[i], o);
        *o++ = '\n';
    }
    return (long)(o - out);
}

/* str(int(v)) of an integral v held as a double. */
static int write_int(double v, char *out)
{
    long long i = (long long)v;
    char *o = out;
    if (i < 0) {
        *o++ = '-';
        i = -i;
    }
    return (int)(o - out) + write_digits((uint64_t)i, o);
}

/* Rows 0 .. rows-1 of a column-major block (column j at block + j*ld) as CSV lines ending in \r\n.
 * kinds[j]: 0 repr of a float, 1 an integer, 2 a label: labels[label_at[j] + (int)v]. A float equal
 * (bit for bit) to the one above it takes that one's text (constant columns cost little).
 * out must hold rows * (cols * 26 + 2) characters plus the labels' lengths and SLACK (64) bytes (the
 * digits are stored in whole words); returns the length,
 * or -1 when out of memory. */
long csv_rows(const double *block, long ld, int rows, int cols, const int *kinds, const char *const *labels,
              const int *label_at, char *out)
{
    char **above = malloc((size_t)cols * sizeof *above);     /* where each column's last text starts */
    int *len = malloc((size_t)cols * sizeof *len);
    if (!above || !len) {
        free(above);
        free(len);
        return -1;
    }
    char *o = out;
    for (int r = 0; r < rows; r++) {
        for (int j = 0; j < cols; j++) {
            const double *v = block + j * ld + r;
            if (j)
                *o++ = ',';
            if (kinds[j] == 0) {
                if (r && !memcmp(v, v - 1, sizeof *v)) {
                    memcpy(o, above[j], (size_t)len[j]);
                } else {
                    len[j] = csv_repr(*v, o);
                }
                above[j] = o;
                o += len[j];
            } else if (kinds[j] == 1) {
                o += write_int(*v, o);
            } else {
                const char *name = labels[label_at[j] + (int)*v];
                size_t n = strlen(name);
                memcpy(o, name, n);
                o += n;
            }
        }
        *o++ = '\r';
        *o++ = '\n';
    }
    free(above);
    free(len);
    return (long)(o - out);
}
