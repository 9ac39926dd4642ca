/* CSV rows as Python writes them: every double as repr() does (the shortest decimal that reads
 * back to the same bits, the closest such one, ties to an even last digit, in repr's layout), whole
 * columns as integers or as labels. Used by wavecosim/observers/recorder.py through ctypes on a
 * block of rows at a time.
 *
 * Shortest digits, exactly: v = m 2^e has the rounding interval (m -+ 1/2) 2^e (the lower half
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

/* The decimal digits of d (no leading zeros) into out; returns how many. */
static int write_digits(uint64_t d, char *out)
{
    int n = 1;
    for (uint64_t p = 10; n < 20 && d >= p; p *= 10)
        n++;
    char *o = out + n;
    while (d >= 100) {
        int r = (int)(d % 100);
        d /= 100;
        *--o = DIGIT_PAIRS[2 * r + 1];
        *--o = DIGIT_PAIRS[2 * r];
    }
    if (d >= 10) {
        *--o = DIGIT_PAIRS[2 * d + 1];
        *--o = DIGIT_PAIRS[2 * d];
    } else {
        *--o = (char)('0' + d);
    }
    return n;
}

/* repr's layout of digits d1..dn with value 0.d1..dn 10^decpt: exponent form when decpt - 1 < -4
 * or >= 16 (e-05, e+16), else fixed with ".0" after integral values. */
static int layout(const char *dg, int n, int decpt, char *out)
{
    char *o = out;
    int x = decpt - 1;
    if (x < -4 || x >= 16) {
        *o++ = dg[0];
        if (n > 1) {
            *o++ = '.';
            memcpy(o, dg + 1, (size_t)(n - 1));
            o += n - 1;
        }
        *o++ = 'e';
        *o++ = x < 0 ? '-' : '+';
        int ax = x < 0 ? -x : x;
        if (ax >= 100)
            *o++ = (char)('0' + ax / 100);
        *o++ = (char)('0' + (ax / 10) % 10);
        *o++ = (char)('0' + ax % 10);
    } else if (decpt <= 0) {
        *o++ = '0';
        *o++ = '.';
        memset(o, '0', (size_t)-decpt);
        o += -decpt;
        memcpy(o, dg, (size_t)n);
        o += n;
    } else if (decpt >= n) {
        memcpy(o, dg, (size_t)n);
        o += n;
        memset(o, '0', (size_t)(decpt - n));
        o += decpt - n;
        *o++ = '.';
        *o++ = '0';
    } else {
        memcpy(o, dg, (size_t)decpt);
        o += decpt;
        *o++ = '.';
        memcpy(o, dg + decpt, (size_t)(n - decpt));
        o += n - decpt;
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
    if (neg)
        *o++ = '-';
    if (be == 0 && frac == 0) {
        memcpy(o, "0.0", 3);
        return (int)(o - out) + 3;
    }
    uint64_t m = be ? frac | (UINT64_C(1) << 52) : frac;
    int e = (be ? be : 1) - 1075, dexp = 0;
    uint64_t d = e < 7 ? shortest(m, e, !(m & 1), frac == 0 && be > 1, &dexp)
                       : shortest_printf(fabs(v), frac == 0, &dexp);
    char dg[24];
    int n = write_digits(d, dg);
    return (int)(o - out) + layout(dg, n, n + dexp, o);
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
 * out must hold rows * (cols * 26 + 2) characters plus the labels' lengths; returns the length,
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
