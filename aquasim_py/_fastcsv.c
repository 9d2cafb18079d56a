/* The trace's two bulk loops in C (aquasim_py/trace.py keeps the Python reference of each, which
 * runs when this module is missing and which the tests hold equal to it):
 *
 * csv_rows(columns, n)   the CSV text of a streamed chunk's rows, as UTF-8 bytes: what
 *                        trace._csv_lines writes (and so DataFrame.to_csv), byte for byte.
 * push_rows(rows, cols)  a batch of row tuples into a table's typed columns: what
 *                        Table._flush's zip(*rows) + _Column.push_many do, for every column
 *                        whose values all fit it as they are; the other columns are left
 *                        untouched and named in the result, for the Python path to take.
 *
 * Neither keeps state between calls (all of it lives in the caller's objects), no threads. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

/* ------------------------------------------------------------------ a growing byte buffer */
typedef struct {
    char *p;
    Py_ssize_t n, cap;
} Buf;

static inline int buf_reserve(Buf *b, Py_ssize_t more) {
    if (b->n + more <= b->cap) return 0;
    Py_ssize_t cap = b->cap ? b->cap : 4096;
    while (cap < b->n + more) {
        if (cap > PY_SSIZE_T_MAX / 2) {
            PyErr_NoMemory();
            return -1;
        }
        cap *= 2;
    }
    char *p = PyMem_Realloc(b->p, (size_t)cap);
    if (p == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    b->p = p;
    b->cap = cap;
    return 0;
}

static inline int buf_add(Buf *b, const char *s, Py_ssize_t len) {
    if (buf_reserve(b, len) < 0) return -1;
    memcpy(b->p + b->n, s, (size_t)len);
    b->n += len;
    return 0;
}

/* ------------------------------------------------------------------ csv_rows */
/* A chunk's float fields, each distinct value (by its bits) formatted once, as
 * trace._float_fields does: a static link's delay and SNR recur with every packet on it.
 * Open addressing over the bit patterns; the texts live in one arena. */
typedef struct {
    uint64_t *keys;
    Py_ssize_t *off; /* offset of the text in the arena, -1 for an empty slot */
    unsigned char *len;
    size_t mask;
    int shift; /* 64 - log2(size): the slot is the top bits of a Fibonacci hash */
    Buf arena;
} FloatText;

static int ft_init(FloatText *ft, Py_ssize_t values) {
    size_t size = 64;
    ft->shift = 64 - 6;
    while (size < (size_t)values + (size_t)values / 2) { /* load <= 2/3 */
        size *= 2;
        ft->shift--;
    }
    ft->mask = size - 1;
    ft->keys = PyMem_Malloc(size * sizeof(uint64_t));
    ft->off = PyMem_Malloc(size * sizeof(Py_ssize_t));
    ft->len = PyMem_Malloc(size);
    ft->arena = (Buf){NULL, 0, 0};
    if (ft->keys == NULL || ft->off == NULL || ft->len == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    for (size_t i = 0; i < size; i++) ft->off[i] = -1;
    return 0;
}

static void ft_free(FloatText *ft) {
    PyMem_Free(ft->keys);
    PyMem_Free(ft->off);
    PyMem_Free(ft->len);
    PyMem_Free(ft->arena.p);
}

#ifdef __SIZEOF_INT128__
/* float.__repr__ of the doubles of everyday magnitude, without CPython's dtoa (about 0.55 us
 * for a 17-digit value, most of a trace row's formatting): repr is the shortest decimal that
 * reads back as v (David Gay's mode 0), and among several of that length the one closest to v.
 * With v = m 2^e and 2^-10 <= |v| < 2^51, v's round-trip interval scaled by 10^q to 18-19
 * digits is held exactly in 128-bit integers; the shortest candidates are the multiples of the
 * largest power of ten inside it, and the closest of them is v rounded to it (an exact tie,
 * which occurs for |v| >= 2^35 or so, to the even digit, as dtoa). Everything else (zero,
 * subnormals, tiny or huge values, inf) returns 0 and goes to PyOS_double_to_string.
 * tests/test_trace_csv.py holds it equal to repr on every binary exponent of the range. */
typedef unsigned __int128 u128;

static const uint64_t POW10[20] = {
    1ULL, 10ULL, 100ULL, 1000ULL, 10000ULL, 100000ULL, 1000000ULL, 10000000ULL, 100000000ULL,
    1000000000ULL, 10000000000ULL, 100000000000ULL, 1000000000000ULL, 10000000000000ULL,
    100000000000000ULL, 1000000000000000ULL, 10000000000000000ULL, 100000000000000000ULL,
    1000000000000000000ULL, 10000000000000000000ULL,
};

static const char DIGITS2[201] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

static int short_repr(double v, char *out) {
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    int biased = (int)((bits >> 52) & 0x7FF);
    uint64_t frac = bits & ((UINT64_C(1) << 52) - 1);
    int e = biased - 1075; /* |v| = m 2^e, m = frac + 2^52 (normal numbers) */
    if (biased == 0 || e < -62 || e > -2) return 0;
    uint64_t m = frac | (UINT64_C(1) << 52);
    int even = (m & 1) == 0; /* a read-back rounds half to even: v's bounds belong to it then */
    /* v and the bounds of the interval that reads back as v, in units of 2^(e-2): the bound
     * below is closer when m is a power of two (the next double down is half as far) */
    uint64_t V = 4 * m, H = V + 2, L = frac == 0 && biased > 1 ? V - 1 : V - 2;
    int k = 2 - e;                     /* value = X / 2^k, 4 <= k <= 64 */
    int x = e + 52;                    /* 2^x <= |v| < 2^(x+1), -10 <= x <= 50 */
    int d = x >= 0 ? (x * 78913) >> 18 : -((-x * 78913 + 262143) >> 18); /* floor(x log10 2) */
    int q = 17 - d;                    /* |v| 10^q in [1e17, 2e18): it fits in 64 bits */
    u128 p = q <= 19 ? (u128)POW10[q] : (u128)POW10[19] * POW10[q - 19];
    u128 mask = ((u128)1 << k) - 1;
    u128 vn = (u128)V * p, hn = (u128)H * p, ln = (u128)L * p;
    uint64_t vr = (uint64_t)(vn >> k);
    u128 vf = vn & mask; /* vr's fraction, in units of 2^-k */
    /* the integers in the interval scaled by 10^q */
    uint64_t hi = (uint64_t)(hn >> k) - (!even && (hn & mask) == 0);
    uint64_t lo = (uint64_t)(ln >> k) + ((ln & mask) != 0 || !even);
    /* the largest j such that a multiple of 10^j lies in [lo, hi]: those are the shortest;
     * meanwhile vr loses the same digits, the last one removed and whether all before it were
     * zero kept for the rounding below (one multiply-shift per division by 10) */
    int j = 0, last = 0, zeros = 1;
    for (;;) {
        uint64_t nlo = lo / 10 + (lo % 10 != 0), nhi = hi / 10;
        if (nlo > nhi) break;
        lo = nlo;
        hi = nhi;
        zeros &= last == 0;
        last = (int)(vr % 10);
        vr /= 10;
        j++;
    }
    /* v scaled by 10^(q-j) rounded to the nearest integer, kept inside the interval; an exact
     * tie (only for |v| >= 2^35 or so) to the even digit, as dtoa */
    int above, tie;
    if (j == 0) {
        u128 half = (u128)1 << (k - 1);
        above = vf > half;
        tie = vf == half;
    } else {
        int exact = zeros && vf == 0; /* the removed digits after the last one, and vr's fraction */
        above = last > 5 || (last == 5 && !exact);
        tie = last == 5 && exact;
    }
    uint64_t c = vr + (above || (tie && (vr & 1)));
    if (c < lo) c = lo;
    if (c > hi) c = hi;
    /* the digits of c (no trailing zero: else a multiple of 10^(j+1) were inside): blocks of
     * eight in 32-bit arithmetic, two digits at a time */
    char dig[24];
    char *dp = dig + 24;
    while (c >= 100000000) {
        uint32_t b = (uint32_t)(c % 100000000);
        c /= 100000000;
        for (int t = 0; t < 4; t++, b /= 100) {
            *--dp = DIGITS2[2 * (b % 100) + 1];
            *--dp = DIGITS2[2 * (b % 100)];
        }
    }
    uint32_t b = (uint32_t)c;
    while (b >= 100) {
        *--dp = DIGITS2[2 * (b % 100) + 1];
        *--dp = DIGITS2[2 * (b % 100)];
        b /= 100;
    }
    if (b >= 10) {
        *--dp = DIGITS2[2 * b + 1];
        *--dp = DIGITS2[2 * b];
    } else {
        *--dp = (char)('0' + b);
    }
    const char *ds = dp;
    int nd = (int)(dig + 24 - dp);
    int decpt = nd + j - q; /* |v| ~ 0.d1d2... 10^decpt */
    char *o = out;
    if (bits >> 63) *o++ = '-';
    if (decpt <= -4 || decpt > 16) { /* repr's switch to exponents (pystrtod.c, 'r') */
        *o++ = ds[0];
        if (nd > 1) {
            *o++ = '.';
            memcpy(o, ds + 1, (size_t)(nd - 1));
            o += nd - 1;
        }
        int x10 = decpt - 1;
        *o++ = 'e';
        *o++ = x10 < 0 ? '-' : '+';
        if (x10 < 0) x10 = -x10;
        if (x10 >= 100) *o++ = (char)('0' + x10 / 100);
        *o++ = (char)('0' + x10 / 10 % 10);
        *o++ = (char)('0' + x10 % 10);
    } else if (decpt <= 0) { /* 0.000ddd */
        *o++ = '0';
        *o++ = '.';
        memset(o, '0', (size_t)-decpt);
        o += -decpt;
        memcpy(o, ds, (size_t)nd);
        o += nd;
    } else if (decpt >= nd) { /* ddd000.0 */
        memcpy(o, ds, (size_t)nd);
        o += nd;
        memset(o, '0', (size_t)(decpt - nd));
        o += decpt - nd;
        *o++ = '.';
        *o++ = '0';
    } else { /* ddd.ddd */
        memcpy(o, ds, (size_t)decpt);
        o += decpt;
        *o++ = '.';
        memcpy(o, ds + decpt, (size_t)(nd - decpt));
        o += nd - decpt;
    }
    return (int)(o - out);
}
#endif

/* The slot of v's field: float.__repr__(v) exactly (short_repr, or the same call with the same
 * flags as CPython's float_repr); -1 for NaN (pandas' na_rep ""), -2 on an error. */
static int32_t ft_slot(FloatText *ft, double v) {
    if (isnan(v)) return -1;
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    size_t i = (size_t)((bits * UINT64_C(0x9E3779B97F4A7C15)) >> ft->shift);
    while (ft->off[i] >= 0) {
        if (ft->keys[i] == bits) return (int32_t)i;
        i = (i + 1) & ft->mask;
    }
    Py_ssize_t len = 0; /* at most 24 characters ("-2.2250738585072014e-308") */
#ifdef __SIZEOF_INT128__
    char tmp[32];
    len = short_repr(v, tmp);
    if (len && buf_add(&ft->arena, tmp, len) < 0) return -2;
#endif
    if (!len) {
        char *s = PyOS_double_to_string(v, 'r', 0, Py_DTSF_ADD_DOT_0, NULL);
        if (s == NULL) return -2;
        len = (Py_ssize_t)strlen(s);
        int err = buf_add(&ft->arena, s, len);
        PyMem_Free(s);
        if (err < 0) return -2;
    }
    ft->keys[i] = bits;
    ft->off[i] = ft->arena.n - len;
    ft->len[i] = (unsigned char)len;
    return (int32_t)i;
}

/* the length of str(v) of an int64, and its text written at o */
static int int_len(int64_t v) {
    /* the magnitude as unsigned: -(2**63) has no positive int64 */
    uint64_t m = v < 0 ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
    int len = 1 + (v < 0);
    while (m >= 10) {
        m /= 10;
        len++;
    }
    return len;
}

static void int_put(char *o, int64_t v, int len) {
    uint64_t m = v < 0 ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
    char *p = o + len;
    do {
        *--p = (char)('0' + m % 10);
        m /= 10;
    } while (m);
    if (v < 0) *--p = '-';
}

/* one column of the chunk, as the Python side hands it over */
typedef struct {
    char kind;            /* 'f' float64, 'i' int64, 'c' int32 codes into texts, 's' texts */
    Py_buffer view;       /* 'f', 'i', 'c': the values */
    int has_view;
    PyObject *texts;      /* 'c': a list of each category's field; 's': a list of the fields */
    Py_ssize_t ntexts;
    int32_t *slots;       /* 'f': each row's slot in the FloatText, -1 for NaN */
    const char **ptr;     /* 'c': each category's field (UTF-8); 's': each row's */
    Py_ssize_t *len;      /* their lengths */
} Col;

/* UTF-8 of a field (a str), cached on the str itself by CPython */
static const char *field_utf8(PyObject *texts, Py_ssize_t i, Py_ssize_t *len) {
    PyObject *s = PyList_GET_ITEM(texts, i);
    if (!PyUnicode_Check(s)) {
        PyErr_SetString(PyExc_TypeError, "csv_rows: fields must be str");
        return NULL;
    }
    return PyUnicode_AsUTF8AndSize(s, len);
}

static PyObject *csv_rows(PyObject *self, PyObject *args) {
    PyObject *columns;
    Py_ssize_t n;
    if (!PyArg_ParseTuple(args, "O!n:csv_rows", &PyList_Type, &columns, &n)) return NULL;
    Py_ssize_t ncol = PyList_GET_SIZE(columns);
    if (n < 0 || ncol < 1) {
        PyErr_SetString(PyExc_ValueError, "csv_rows: no columns or a negative row count");
        return NULL;
    }
    Col *cols = PyMem_Calloc((size_t)ncol, sizeof(Col));
    if (cols == NULL) return PyErr_NoMemory();
    FloatText ft = {NULL, NULL, NULL, 0, 0, {NULL, 0, 0}};
    PyObject *result = NULL;
    Py_ssize_t nfloat = 0;

    /* take each column: (kind, values, texts) */
    for (Py_ssize_t j = 0; j < ncol; j++) {
        PyObject *t = PyList_GET_ITEM(columns, j);
        const char *kind;
        PyObject *values, *texts;
        if (!PyArg_ParseTuple(t, "sOO:csv_rows column", &kind, &values, &texts)) goto done;
        Col *c = &cols[j];
        c->kind = kind[0];
        if (c->kind == 's') {
            if (!PyList_Check(values) || PyList_GET_SIZE(values) != n) {
                PyErr_SetString(PyExc_ValueError, "csv_rows: a text column must be a list of n fields");
                goto done;
            }
            c->texts = values;
            continue;
        }
        Py_ssize_t item = c->kind == 'c' ? 4 : 8;
        const char *fmt = c->kind == 'f' ? "d" : c->kind == 'i' ? "q" : c->kind == 'c' ? "i" : NULL;
        if (fmt == NULL) {
            PyErr_Format(PyExc_ValueError, "csv_rows: unknown column kind %R", PyTuple_GET_ITEM(t, 0));
            goto done;
        }
        if (PyObject_GetBuffer(values, &c->view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) goto done;
        c->has_view = 1;
        /* numpy says "<d" / "<q" / "<i" or "l" where long is 64 bits: check the item size and
         * the type letter, not the whole string */
        const char *f = c->view.format ? c->view.format : "B";
        if (*f == '<' || *f == '=' || *f == '@') f++;
        int letter_ok = c->kind == 'f' ? *f == 'd' : (*f == 'q' || *f == 'l' || *f == 'i');
        if (c->view.itemsize != item || !letter_ok || c->view.len != n * item) {
            PyErr_Format(PyExc_ValueError, "csv_rows: column %zd is not %zd values of type %s", j, n, fmt);
            goto done;
        }
        if (c->kind == 'c') {
            if (!PyList_Check(texts)) {
                PyErr_SetString(PyExc_TypeError, "csv_rows: a category column needs a list of fields");
                goto done;
            }
            c->texts = texts;
            c->ntexts = PyList_GET_SIZE(texts);
        }
        if (c->kind == 'f') nfloat += n;
    }
    if (nfloat > INT32_MAX / 2) { /* slots are int32 (a chunk holds a few thousand rows) */
        PyErr_SetString(PyExc_ValueError, "csv_rows: too many float values for one call");
        goto done;
    }
    if (ft_init(&ft, nfloat) < 0) goto done;
    /* the float fields a column at a time: the formatter's branches then follow one column's
     * magnitudes (rows alternating between a time and a delay took twice as long) */
    for (Py_ssize_t j = 0; j < ncol; j++) {
        Col *c = &cols[j];
        if (c->kind != 'f') continue;
        c->slots = PyMem_Malloc((size_t)(n ? n : 1) * sizeof(int32_t));
        if (c->slots == NULL) {
            PyErr_NoMemory();
            goto done;
        }
        const double *v = c->view.buf;
        for (Py_ssize_t r = 0; r < n; r++)
            if ((c->slots[r] = ft_slot(&ft, v[r])) == -2) goto done;
    }

    /* the text fields' UTF-8 (cached on each str by CPython), and the exact size of the text:
     * it is then written in place into one bytes object (a growing buffer, copied at the end,
     * cost page faults on every chunk) */
    Py_ssize_t total = n * ncol; /* the commas and the line ends */
    for (Py_ssize_t j = 0; j < ncol; j++) {
        Col *c = &cols[j];
        if (c->kind == 'c' || c->kind == 's') {
            Py_ssize_t m = c->kind == 'c' ? c->ntexts : n;
            c->ptr = PyMem_Malloc((size_t)(m ? m : 1) * sizeof(char *));
            c->len = PyMem_Malloc((size_t)(m ? m : 1) * sizeof(Py_ssize_t));
            if (c->ptr == NULL || c->len == NULL) {
                PyErr_NoMemory();
                goto done;
            }
            for (Py_ssize_t i = 0; i < m; i++)
                if ((c->ptr[i] = field_utf8(c->texts, i, &c->len[i])) == NULL) goto done;
        }
        for (Py_ssize_t r = 0; r < n; r++) {
            if (c->kind == 'f') {
                int32_t i = c->slots[r];
                total += i >= 0 ? ft.len[i] : 0;
            } else if (c->kind == 'i') {
                total += int_len(((const int64_t *)c->view.buf)[r]);
            } else if (c->kind == 's') {
                total += c->len[r];
            } else {
                int32_t i = ((const int32_t *)c->view.buf)[r];
                if (i < 0 || i >= c->ntexts) {
                    PyErr_Format(PyExc_IndexError, "csv_rows: code %d beyond %zd categories", (int)i, c->ntexts);
                    goto done;
                }
                total += c->len[i];
            }
        }
    }
    result = PyBytes_FromStringAndSize(NULL, total);
    if (result == NULL) goto done;
    char *o = PyBytes_AS_STRING(result);
    for (Py_ssize_t r = 0; r < n; r++) {
        for (Py_ssize_t j = 0; j < ncol; j++) {
            Col *c = &cols[j];
            if (j) *o++ = ',';
            if (c->kind == 'f') {
                int32_t i = c->slots[r];
                if (i >= 0) {
                    memcpy(o, ft.arena.p + ft.off[i], ft.len[i]);
                    o += ft.len[i];
                }
            } else if (c->kind == 'i') {
                int64_t v = ((const int64_t *)c->view.buf)[r];
                int len = int_len(v);
                int_put(o, v, len);
                o += len;
            } else {
                Py_ssize_t i = c->kind == 'c' ? ((const int32_t *)c->view.buf)[r] : r;
                memcpy(o, c->ptr[i], (size_t)c->len[i]);
                o += c->len[i];
            }
        }
        *o++ = '\n';
    }
    assert(o == PyBytes_AS_STRING(result) + total);

done:
    for (Py_ssize_t j = 0; j < ncol; j++) {
        if (cols[j].has_view) PyBuffer_Release(&cols[j].view);
        PyMem_Free(cols[j].slots);
        PyMem_Free((void *)cols[j].ptr);
        PyMem_Free(cols[j].len);
    }
    PyMem_Free(cols);
    ft_free(&ft);
    if (PyErr_Occurred()) Py_CLEAR(result);
    return result;
}

/* ------------------------------------------------------------------ push_rows */
/* Column j's values of every row as doubles (kind 'f': what array('d', values) stores for an
 * exact float or int) or int64s (kind 'i': array('q', values) for an exact int) into dst.
 * 0: done; 1: a value the fast path does not take (the column is left to Python); -1: error. */
static int take_numbers(PyObject *rows, Py_ssize_t j, char kind, char *dst) {
    Py_ssize_t n = PyList_GET_SIZE(rows);
    for (Py_ssize_t r = 0; r < n; r++) {
        PyObject *v = PyTuple_GET_ITEM(PyList_GET_ITEM(rows, r), j);
        if (kind == 'f') {
            double x;
            if (PyFloat_CheckExact(v)) {
                x = PyFloat_AS_DOUBLE(v);
            } else if (PyLong_CheckExact(v)) {
                x = PyLong_AsDouble(v);
                if (x == -1.0 && PyErr_Occurred()) { /* too large: Python's path decides */
                    PyErr_Clear();
                    return 1;
                }
            } else {
                return 1;
            }
            memcpy(dst + 8 * r, &x, 8);
        } else {
            if (!PyLong_CheckExact(v)) return 1; /* bools, floats, None, numpy scalars */
            int overflow;
            long long x = PyLong_AsLongLongAndOverflow(v, &overflow);
            if (overflow) return 1;
            if (x == -1 && PyErr_Occurred()) return -1;
            int64_t y = (int64_t)x;
            memcpy(dst + 8 * r, &y, 8);
        }
    }
    return 0;
}

/* Column j's values as category codes (new categories coded in order of first appearance,
 * as _Column.push_many); only strings and None (exact types), else 1 and cats untouched. */
static int take_codes(PyObject *rows, Py_ssize_t j, PyObject *cats, char *dst) {
    Py_ssize_t n = PyList_GET_SIZE(rows);
    for (Py_ssize_t r = 0; r < n; r++) {
        PyObject *v = PyTuple_GET_ITEM(PyList_GET_ITEM(rows, r), j);
        if (v != Py_None && !PyUnicode_CheckExact(v)) return 1;
    }
    for (Py_ssize_t r = 0; r < n; r++) {
        PyObject *v = PyTuple_GET_ITEM(PyList_GET_ITEM(rows, r), j);
        PyObject *code = PyDict_GetItemWithError(cats, v); /* borrowed */
        long c;
        if (code == NULL) {
            if (PyErr_Occurred()) return -1;
            Py_ssize_t k = PyDict_GET_SIZE(cats);
            if (k >= INT32_MAX) {
                PyErr_SetString(PyExc_OverflowError, "push_rows: too many categories");
                return -1;
            }
            PyObject *nc = PyLong_FromSsize_t(k);
            if (nc == NULL) return -1;
            int err = PyDict_SetItem(cats, v, nc);
            Py_DECREF(nc);
            if (err < 0) return -1;
            c = (long)k;
        } else {
            c = PyLong_AsLong(code);
            if (c == -1 && PyErr_Occurred()) return -1;
        }
        int32_t c32 = (int32_t)c;
        memcpy(dst + 4 * r, &c32, 4);
    }
    return 0;
}

/* an array's item size in bytes (0 if it has none): the bytes appended must be its items */
static Py_ssize_t item_size(PyObject *data) {
    PyObject *size = PyObject_GetAttrString(data, "itemsize");
    Py_ssize_t n = size ? PyLong_AsSsize_t(size) : 0;
    Py_XDECREF(size);
    if (n < 0 || PyErr_Occurred()) {
        PyErr_Clear();
        n = 0;
    }
    return n;
}

static PyObject *push_rows(PyObject *self, PyObject *args) {
    PyObject *rows, *columns;
    if (!PyArg_ParseTuple(args, "O!O!:push_rows", &PyList_Type, &rows, &PyList_Type, &columns)) return NULL;
    Py_ssize_t n = PyList_GET_SIZE(rows), ncol = PyList_GET_SIZE(columns);
    PyObject *left = PyList_New(0); /* the columns left to the Python path */
    if (left == NULL) return NULL;
    /* every row a tuple of exactly one value per column, or Python takes them all (zip's rules) */
    int shaped = 1;
    for (Py_ssize_t r = 0; r < n && shaped; r++) {
        PyObject *t = PyList_GET_ITEM(rows, r);
        shaped = PyTuple_CheckExact(t) && PyTuple_GET_SIZE(t) == ncol;
    }
    PyObject *tmp = NULL;
    for (Py_ssize_t j = 0; j < ncol; j++) {
        PyObject *spec = PyList_GET_ITEM(columns, j);
        const char *kind;
        PyObject *data, *cats;
        if (!PyArg_ParseTuple(spec, "sOO:push_rows column", &kind, &data, &cats)) goto fail;
        int res = 1;
        if (shaped && kind[0] == 'o' && PyList_CheckExact(data)) {
            for (Py_ssize_t r = 0; r < n; r++)
                if (PyList_Append(data, PyTuple_GET_ITEM(PyList_GET_ITEM(rows, r), j)) < 0) goto fail;
            res = 0;
        } else if (shaped && (kind[0] == 'f' || kind[0] == 'i' || (kind[0] == 'c' && PyDict_CheckExact(cats))) &&
                   item_size(data) == (kind[0] == 'c' ? 4 : 8)) {
            Py_ssize_t item = kind[0] == 'c' ? 4 : 8;
            tmp = PyBytes_FromStringAndSize(NULL, n * item);
            if (tmp == NULL) goto fail;
            char *dst = PyBytes_AS_STRING(tmp);
            res = kind[0] == 'c' ? take_codes(rows, j, cats, dst) : take_numbers(rows, j, kind[0], dst);
            if (res < 0) goto fail;
            if (res == 0) { /* the column's own array grows by the new values (C-level memcpy) */
                PyObject *ok = PyObject_CallMethod(data, "frombytes", "O", tmp);
                if (ok == NULL) goto fail;
                Py_DECREF(ok);
            }
            Py_CLEAR(tmp);
        }
        if (res) {
            PyObject *jj = PyLong_FromSsize_t(j);
            if (jj == NULL) goto fail;
            int err = PyList_Append(left, jj);
            Py_DECREF(jj);
            if (err < 0) goto fail;
        }
    }
    return left;
fail:
    Py_XDECREF(tmp);
    Py_DECREF(left);
    return NULL;
}

/* short_repr of one float, None where it declines (for the tests against repr) */
static PyObject *fast_repr(PyObject *self, PyObject *arg) {
    double v = PyFloat_AsDouble(arg);
    if (v == -1.0 && PyErr_Occurred()) return NULL;
#ifdef __SIZEOF_INT128__
    char tmp[32];
    int len = short_repr(v, tmp);
    if (len) return PyUnicode_FromStringAndSize(tmp, len);
#endif
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"fast_repr", fast_repr, METH_O,
     "fast_repr(v) -> str | None: float.__repr__(v) by the formatter csv_rows uses for the "
     "values of everyday magnitude; None outside them (csv_rows then asks CPython's dtoa)."},
    {"csv_rows", csv_rows, METH_VARARGS,
     "csv_rows(columns, n) -> bytes: the CSV lines (UTF-8) of n rows; columns: a list of (kind, "
     "values, texts): ('f', float64 buffer, None), ('i', int64 buffer, None), ('c', int32 codes, "
     "list of each category's field), ('s', list of the n fields, None)."},
    {"push_rows", push_rows, METH_VARARGS,
     "push_rows(rows, columns) -> list[int]: append row tuples to typed columns, given as a list of "
     "(kind, data, cats); returns the indices of the columns left untouched for the Python path."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_fastcsv", "The trace's bulk loops in C (see aquasim_py/trace.py).", 0, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__fastcsv(void) { return PyModule_Create(&module); }
