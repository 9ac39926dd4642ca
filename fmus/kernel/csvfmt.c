/* CSV rows as Python writes them: every double as repr() does (the shortest decimal that reads
 * back to the same bits, the closest such one, ties to an even last digit, in repr's layout), whole
 * columns as integers or as labels. Used by wavecosim/observers/recorder.py through ctypes on a
 * block of rows at a time. Two routes give the same digits: the fast one (Ryu's method, below
 * `shortest_fast`) writes the files; the exact one, slower, is the reference it is checked against
 * (csv_lines; tests/test_csvtext.py, scripts/csvfmt_check.py).
 *
 * Shortest digits, exactly (the reference route): v = m 2^e has the rounding interval (m -+ 1/2) 2^e (the lower half
 * 1/4 for a power of two); scaled by 4 its ends and centre are X 2^(e-2) with X = 4m-2|4m-1, 4m,
 * 4m+2. Times 10^k (k chosen so the interval is at least 2 units wide) they are computed exactly
 * with 64-bit limbs; then decimal digits are dropped while a multiple of 10 stays in the interval,
 * and the last kept digit is rounded to the centre. Values of 2^59 and above take a slower exact
 * route through printf and strtod (both correctly rounded in glibc).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_K 345                    /* 10^k for k = 0 .. MAX_K: enough for the smallest subnormal */
#define LIMBS 20                     /* 10^345 < 2^1147: 18 limbs, and one more for the product */

typedef unsigned __int128 u128;

static void pow5_tables(void);
static uint64_t pow10_limbs[MAX_K + 1][LIMBS];
static int pow10_len[MAX_K + 1];
static int ready = 0;

/* The table of 10^k in limbs (least significant first); called once before any formatting. */
void csv_init(void)
{
    if (ready)
        return;
    memset(pow10_limbs, 0, sizeof pow10_limbs);
    pow10_limbs[0][0] = 1;
    pow10_len[0] = 1;
    for (int k = 1; k <= MAX_K; k++) {
        uint64_t carry = 0;
        int n = pow10_len[k - 1];
        for (int i = 0; i < n; i++) {
            u128 p = (u128)pow10_limbs[k - 1][i] * 10u + carry;
            pow10_limbs[k][i] = (uint64_t)p;
            carry = (uint64_t)(p >> 64);
        }
        if (carry)
            pow10_limbs[k][n++] = carry;
        pow10_len[k] = n;
    }
    pow5_tables();
    ready = 1;
}

/* x 10^k 2^-s (s may be negative, then |s| <= 8): the integer part (< 2^64 by the choice of k), and
 * whether the fraction is zero, or its first bit (half) and whether anything follows it. */
typedef struct { uint64_t q; int exact; int half; int sticky; } Scaled;

static Scaled scale(uint64_t x, int k, int s)
{
    uint64_t p[LIMBS + 1];
    int n = pow10_len[k];
    uint64_t carry = 0;
    Scaled r = {0, 1, 0, 0};
    for (int i = 0; i < n; i++) {
        u128 t = (u128)pow10_limbs[k][i] * x + carry;
        p[i] = (uint64_t)t;
        carry = (uint64_t)(t >> 64);
    }
    p[n++] = carry;
    p[n] = 0;
    if (s <= 0) {
        r.q = p[0] << -s;            /* e in 2..6: the product is below 2^59, shifted by at most 4 */
        return r;
    }
    int w = s >> 6, b = s & 63;
    r.q = b ? (p[w] >> b) | (w + 1 < n + 1 ? p[w + 1] << (64 - b) : 0) : p[w];
    int hb = s - 1;
    r.half = (int)((p[hb >> 6] >> (hb & 63)) & 1u);
    uint64_t below = (hb & 63) ? (p[hb >> 6] & ((UINT64_C(1) << (hb & 63)) - 1)) : 0;
    for (int i = 0; i < (hb >> 6) && !below; i++)
        below |= p[i];
    r.sticky = below != 0;
    r.exact = !r.half && !r.sticky;
    return r;
}

/* floor(x log10 2) for |x| < 1700. */
static int floor_log10_pow2(int x)
{
    return (int)(((int64_t)x * 78913) >> 18);
}

/* Shortest round-trip digits of a positive finite v (m, e: v = m 2^e, m < 2^53) for e < 7:
 * the digits as an integer and the decimal exponent of its last digit. */
static uint64_t shortest(uint64_t m, int e, int even, int asym, int *dexp)
{
    int k = floor_log10_pow2(-e) + 2;
    if (k < 0)
        k = 0;
    int s = 2 - e;
    Scaled L = scale(4 * m - 1 - !asym, k, s), V = scale(4 * m, k, s), H = scale(4 * m + 2, k, s);
    uint64_t lo = L.q + (!L.exact || !even), hi = H.q - (H.exact && !even);
    uint64_t vq = V.q;
    int removed = 0, last = 0, tail_zero = V.exact;
    for (;;) {                       /* four digits at a time while a multiple of 10^4 fits, then one */
        uint64_t dropped;
        if (hi / 10000 >= (lo + 9999) / 10000) {
            dropped = vq % 10000;
            tail_zero = tail_zero && last == 0 && dropped % 1000 == 0;
            last = (int)(dropped / 1000);
            vq /= 10000, lo = (lo + 9999) / 10000, hi /= 10000, removed += 4;
        } else if (hi / 10 >= (lo + 9) / 10) {
            dropped = vq % 10;
            tail_zero = tail_zero && last == 0;
            last = (int)dropped;
            vq /= 10, lo = (lo + 9) / 10, hi /= 10, removed += 1;
        } else {
            break;
        }
    }
    int up;
    if (removed == 0)
        up = V.half && (V.sticky || (vq & 1));
    else
        up = last > 5 || (last == 5 && (!tail_zero || (vq & 1)));
    if (vq < lo)
        up = 1;
    else if (vq + 1 > hi)
        up = 0;
    *dexp = removed - k;
    return vq + (uint64_t)up;
}

/* The fast route (Ryu's method): with v = m2 2^e2 (m2 of 53 bits, e2 for 4 v = (4 m2) 2^(e2-2)), the
 * interval's ends and centre times 10^-e10 are one 64 x 128-bit product each with a table entry:
 * 5^i cut to its top 125 bits (e2 < 0), or 2^j / 5^q rounded up to 125 bits (e2 >= 0). Whether a
 * dropped part is exactly zero is known from divisibility by 5^q or 2^q (the products alone lose
 * it); digits are then dropped two, then one at a time while the interval still holds a shorter
 * number, and the last kept one is rounded to the centre (ties even). */
#define POW5_BITS 125
#define POW5_COUNT 326               /* 5^i for e2 down to -1076 */
#define POW5_INV_COUNT 342           /* 2^j / 5^q for e2 up to 969 (q <= 291) */
#define POW5_LIMBS 14                /* 5^341 < 2^792 */

static u128 pow5_split[POW5_COUNT];
static u128 pow5_inv_split[POW5_INV_COUNT];

/* Bits of 5^e (1 for e = 0): ceil(e log2 5) for e > 0. */
static int pow5bits(int e)
{
    return (int)(((uint32_t)e * 1217359u) >> 19) + 1;
}

/* floor(e log10 5). */
static int log10_pow5(int e)
{
    return (int)(((uint32_t)e * 732923u) >> 20);
}

/* The 128 bits of x (limbs, least significant first) from bit `at` up (at may be negative: shifted left). */
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

/* Both tables from 5^i in limbs: its top 125 bits, and floor(2^(bits - 1 + 125) / 5^i) + 1 by binary
 * long division starting from the remainder 2^(bits - 1) < 5^i. */
static void pow5_tables(void)
{
    uint64_t p[POW5_LIMBS] = {1}, r[POW5_LIMBS];
    for (int i = 0; i < POW5_INV_COUNT; i++) {
        int bits = pow5bits(i);
        if (i < POW5_COUNT)
            pow5_split[i] = bits_from(p, bits - POW5_BITS);
        memset(r, 0, sizeof r);
        r[(bits - 1) >> 6] = UINT64_C(1) << ((bits - 1) & 63);
        u128 q = 0;
        for (int s = 0; s < POW5_BITS && i > 0; s++) {
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
        pow5_inv_split[i] = (i ? q : (u128)1 << POW5_BITS) + 1;
        uint64_t carry = 0;
        for (int l = 0; l < POW5_LIMBS; l++) {
            u128 t = (u128)p[l] * 5u + carry;
            p[l] = (uint64_t)t;
            carry = (uint64_t)(t >> 64);
        }
    }
}

/* (x * mul) >> j, for j - 64 in 54 .. 61 (every double's case), as two 64-bit shifts. */
static inline uint64_t mul_shift(uint64_t x, u128 mul, int j)
{
    u128 low = (u128)x * (uint64_t)mul, sum = (low >> 64) + (u128)x * (uint64_t)(mul >> 64);
    int s = j - 64;
    return ((uint64_t)sum >> s) | ((uint64_t)(sum >> 64) << (64 - s));
}

static inline int pow5_factor_at_least(uint64_t x, int p)
{
    int count = 0;
    while (count < p && x % 5 == 0)
        x /= 5, count++;
    return count >= p;
}

/* The digits when a dropped part may be exactly zero (about 1 number in 150): the lower end is
 * included when exact and the mantissa even, and a dropped exact half rounds to an even digit. */
static uint64_t round_exact(uint64_t vr, uint64_t vp, uint64_t vm, int even, int vm_zeros, int vr_zeros,
                            int *removed)
{
    int last = 0, n = 0;
    while (vp / 10 > vm / 10) {
        vm_zeros &= vm % 10 == 0;
        vr_zeros &= last == 0;
        last = (int)(vr % 10);
        vr /= 10, vp /= 10, vm /= 10, n++;
    }
    while (vm_zeros && vm % 10 == 0) {
        vr_zeros &= last == 0;
        last = (int)(vr % 10);
        vr /= 10, vp /= 10, vm /= 10, n++;
    }
    if (vr_zeros && last == 5 && vr % 2 == 0)
        last = 4;
    *removed = n;
    return vr + ((vr == vm && (!even || !vm_zeros)) || last >= 5);
}

/* The digits when no dropped part is exactly zero (the common case): two digits at a time first. */
static inline uint64_t round_common(uint64_t vr, uint64_t vp, uint64_t vm, int *removed)
{
    int up = 0, n = 0;
    if (vp / 100 > vm / 100) {
        up = vr % 100 >= 50;
        vr /= 100, vp /= 100, vm /= 100, n = 2;
    }
    while (vp / 10 > vm / 10) {
        up = vr % 10 >= 5;
        vr /= 10, vp /= 10, vm /= 10, n++;
    }
    *removed = n;
    return vr + (vr == vm || up);
}

/* Shortest round-trip digits of a positive finite v (m2, e2 as in the comment above) as an integer
 * and the decimal exponent of its last digit. */
static uint64_t shortest_fast(uint64_t m2, int e2, int asym, int *dexp)
{
    int even = !(m2 & 1), shift = 1 + !asym;          /* the lower end 4 m2 - 2, or - 1 below a power of two */
    uint64_t mv = 4 * m2, vr, vp, vm;
    int e10, vm_zeros = 0, vr_zeros = 0;
    if (e2 >= 0) {
        int q = floor_log10_pow2(e2) - (e2 > 3), j = -e2 + q + POW5_BITS + pow5bits(q) - 1;
        u128 mul = pow5_inv_split[q];
        e10 = q;
        vr = mul_shift(mv, mul, j), vp = mul_shift(mv + 2, mul, j), vm = mul_shift(mv - shift, mul, j);
        if (q <= 21) {
            if (mv % 5 == 0)
                vr_zeros = pow5_factor_at_least(mv, q);
            else if (even)
                vm_zeros = pow5_factor_at_least(mv - shift, q);
            else
                vp -= (uint64_t)pow5_factor_at_least(mv + 2, q);
        }
    } else {
        int q = log10_pow5(-e2) - (-e2 > 1), i = -e2 - q, j = q - (pow5bits(i) - POW5_BITS);
        u128 mul = pow5_split[i];
        e10 = q + e2;
        vr = mul_shift(mv, mul, j), vp = mul_shift(mv + 2, mul, j), vm = mul_shift(mv - shift, mul, j);
        if (q <= 1) {
            vr_zeros = 1;
            if (even)
                vm_zeros = shift == 2;
            else
                vp--;
        } else if (q < 63) {
            vr_zeros = (mv & ((UINT64_C(1) << q) - 1)) == 0;
        }
    }
    int removed = 0;
    uint64_t out = vm_zeros || vr_zeros ? round_exact(vr, vp, vm, even, vm_zeros, vr_zeros, &removed)
                                        : round_common(vr, vp, vm, &removed);
    *dexp = e10 + removed;
    return out;
}

static int reads_back(const char *text, double v)
{
    return strtod(text, NULL) == v;
}

/* Shortest digits through printf for large normal values (see the file's comment). */
static uint64_t shortest_printf(double v, int power_of_two, int *dexp)
{
    char buf[40];
    for (int p = 15; p <= 17; p++) {
        snprintf(buf, sizeof buf, "%.*e", p - 1, v);
        int ok = reads_back(buf, v);
        char *e = strchr(buf, 'e');
        int x = atoi(e + 1);
        uint64_t d = 0;
        for (const char *c = buf; c < e; c++)
            if (*c >= '0' && *c <= '9')
                d = d * 10 + (uint64_t)(*c - '0');
        if (!ok && p == 16 && power_of_two && strtod(buf, NULL) < v) {
            snprintf(buf, sizeof buf, "%llue%d", (unsigned long long)(d + 1), x - 15);
            ok = reads_back(buf, v);
            d += 1;
        }
        if (ok) {
            *dexp = x - (p - 1);
            while (d % 10 == 0) {
                d /= 10;
                (*dexp)++;
            }
            return d;
        }
    }
    return 0;
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

/* The n <= 17 digits of d at o, with a '.' after the first `point` of them when 0 < point < n;
 * returns the characters written. d is scaled to exactly 17 digits and the text put together in
 * registers and stored in words, so 24 bytes from o are written whatever its length (out has that
 * slack; what lies past the text is overwritten by what follows it). */
static inline int put_digits(uint64_t d, int n, int point, char *o)
{
    uint64_t d17 = d * POW10[17 - n];
    uint32_t high = (uint32_t)(d17 / 100000000), top = high / 100000000;   /* high < 10^9, top < 10 */
    uint64_t w2 = digits8((uint32_t)(d17 - (uint64_t)high * 100000000)), c = w2 >> 56;
    u128 t = (u128)('0' + top) | (u128)digits8(high - top * 100000000) << 8 | (u128)w2 << 72;
    if (point <= 0 || point >= n) {
        memcpy(o, &t, 16);
        memcpy(o + 16, &c, 8);
        return n;
    }
    if (point == 16) {
        memcpy(o, &t, 16);
        o[16] = '.';
        o[17] = (char)c;
        return n + 1;
    }
    u128 low = ((u128)1 << (8 * point)) - 1, r = (t & low) | (u128)'.' << (8 * point) | (t & ~low) << 8;
    uint64_t tail = (uint64_t)(t >> 120) | c << 8;
    memcpy(o, &r, 16);
    memcpy(o + 16, &tail, 8);
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
        memcpy(o, "0.0000", 6);
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

/* repr(v) into out (at most 25 characters) by the fast route, or by the exact reference route
 * (`exact`, kept to check the fast one against); returns the length. */
static int repr_by(double v, char *out, int exact)
{
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    int neg = (int)(bits >> 63), be = (int)((bits >> 52) & 0x7ff);
    uint64_t frac = bits & ((UINT64_C(1) << 52) - 1);
    char *o = out;
    if (be == 0x7ff) {
        if (frac) {
            memcpy(o, "nan", 3);
            return 3;
        }
        if (neg)
            *o++ = '-';
        memcpy(o, "inf", 3);
        return (int)(o - out) + 3;
    }
    *o = '-';                        /* without a branch: signs of data are as good as random */
    o += neg;
    if (be == 0 && frac == 0) {
        memcpy(o, "0.0", 3);
        return (int)(o - out) + 3;
    }
    uint64_t m = be ? frac | (UINT64_C(1) << 52) : frac;
    int e = (be ? be : 1) - 1075, asym = frac == 0 && be > 1, dexp = 0;
    uint64_t d = !exact ? shortest_fast(m, e - 2, asym, &dexp)
               : e < 7 ? shortest(m, e, !(m & 1), asym, &dexp) : shortest_printf(fabs(v), frac == 0, &dexp);
    int n = digit_count(d);
    return (int)(o - out) + layout(d, n, n + dexp, o);
}

int csv_repr(double v, char *out)
{
    return repr_by(v, out, 0);
}

/* v[0 .. n-1], one repr a line ending in \n, by the fast or the exact route (for the checks of the
 * one against the other and against Python's repr); out must hold n * 26 characters and 64 bytes. */
long csv_lines(const double *v, long n, int exact, char *out)
{
    char *o = out;
    for (long i = 0; i < n; i++) {
        o += repr_by(v[i], o, exact);
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
