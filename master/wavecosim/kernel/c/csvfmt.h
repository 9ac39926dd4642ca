/* The CSV formatter (csvfmt.c, libcsvfmt.so; wavecosim/kernel/csvfmt.py binds it through
 * wavecosim/kernel/contract.py). */
#ifndef WAVECOSIM_CSVFMT_H
#define WAVECOSIM_CSVFMT_H

/* The table of 10^k and 10^-k; called once before any formatting. */
void csv_init(void);

/* repr(v) into out (at most 25 characters); returns the length. */
int csv_repr(double v, char *out);

/* v[0 .. n-1], one repr a line ending in \n (for the checks against Python's repr); out must hold
 * n * 26 characters and 64 bytes. */
long csv_lines(const double *v, long n, char *out);

/* Rows 0 .. rows-1 of a column-major block (column j at block + j*ld) as CSV lines ending in \r\n.
 * kinds[j]: 0 repr of a float, 1 an integer, 2 a label: labels[label_at[j] + (int)v]. A float equal
 * (bit for bit) to the one above it takes that one's text (constant columns cost little).
 * out must hold rows * (cols * 26 + 2) characters plus the labels' lengths and SLACK (64) bytes (the
 * digits are stored in whole words); returns the length, or -1 when out of memory. */
long csv_rows(const double *block, long ld, int rows, int cols, const int *kinds, const char *const *labels,
              const int *label_at, char *out);

#endif
