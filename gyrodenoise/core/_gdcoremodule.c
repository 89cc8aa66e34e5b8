/*
 * _gdcoremodule.c -- gyrodenoise._gdcore, the CPython binding of gdcore.c.
 *
 * Buffers go through the buffer protocol (array.array('d'), numpy float64
 * arrays, memoryviews...): no numpy C API, no copies. p must hold at least
 * N_PARAMS float64, s exactly layout(order)[6] float64 (writable); anything
 * else raises (TypeError for a wrong item type, ValueError for a wrong length
 * or an out-of-range order) before the C kernels touch memory.
 *
 *   step(p, s, z, restart) -> float    one sample, s updated in place
 *   run(p, s, z, restarts, out)        the batch loop, GIL released
 *   restart(p, s)                      re-initialise s (counters kept)
 *   layout_total(n) -> int             length of s for AR order n
 *   CONSTANTS                          {name: value} of the P_/S_/M_ indices
 * and the simulated gyro of gdsim.c (gyrodenoise.simulate):
 *   sim_n_params(card) -> int          length of p for a card vector (simkernels.card_vector)
 *   sim_params(card, seed, p)          fill p
 *   sim_n_state(p) -> int              length of s
 *   sim_reset(p, s)                    s at the start
 *   sim_run(p, s, truth, restarts, out) out[i] = one measured sample; GIL released
 *
 * Written against the stable ABI of CPython 3.11 (the buffer protocol joined
 * the limited API in 3.11): one binary, tagged abi3, imports on every
 * CPython >= 3.11 (setup.py py_limited_api).
 */
#define Py_LIMITED_API 0x030B0000
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

#include "gdcore.h"
#include "gdsim.h"

/* float64 in native byte order */
static int is_f64(const Py_buffer *b)
{
    const char *f = b->format;
    if (b->itemsize != 8 || f == NULL)
        return 0;
    if (f[0] == '@' || f[0] == '=')
        f++;
#if PY_LITTLE_ENDIAN
    else if (f[0] == '<')
        f++;
#else
    else if (f[0] == '>' || f[0] == '!')
        f++;
#endif
    return f[0] == 'd' && f[1] == '\0';
}

static int is_u8(const Py_buffer *b)
{
    const char *f = b->format;
    if (b->itemsize != 1)
        return 0;
    if (f == NULL)
        return 1; /* plain bytes */
    if (f[0] == '@' || f[0] == '=' || f[0] == '<' || f[0] == '>' || f[0] == '!')
        f++;
    return (f[0] == '?' || f[0] == 'B' || f[0] == 'b') && f[1] == '\0';
}

/* Acquire a contiguous float64 buffer; on failure set an exception, return -1 */
static int get_f64(PyObject *obj, Py_buffer *b, int writable, const char *name)
{
    if (PyObject_GetBuffer(obj, b, PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0)) < 0) {
        if (PyErr_ExceptionMatches(PyExc_TypeError) || PyErr_ExceptionMatches(PyExc_BufferError)) {
            PyObject *tname = PyType_GetName(Py_TYPE(obj));
            PyErr_Clear();
            if (tname == NULL)
                return -1;
            PyErr_Format(PyExc_TypeError,
                         "%s must be a contiguous%s float64 buffer (array.array('d') or a "
                         "numpy float64 array), got %U",
                         name, writable ? " writable" : "", tname);
            Py_DECREF(tname);
        }
        return -1;
    }
    if (!is_f64(b)) {
        PyErr_Format(PyExc_TypeError, "%s must hold float64 items, got format '%s'", name,
                     b->format ? b->format : "B");
        PyBuffer_Release(b);
        return -1;
    }
    return 0;
}

/* p and s, checked against each other; 0 on success (both held) */
static int get_ps(PyObject *po, PyObject *so, Py_buffer *pb, Py_buffer *sb)
{
    const char *why;
    if (get_f64(po, pb, 0, "p") < 0)
        return -1;
    if (get_f64(so, sb, 1, "s") < 0) {
        PyBuffer_Release(pb);
        return -1;
    }
    why = gd_check((const double *)pb->buf, (long)(pb->len / 8), (long)(sb->len / 8));
    if (why != NULL) {
        PyErr_SetString(PyExc_ValueError, why);
        PyBuffer_Release(sb);
        PyBuffer_Release(pb);
        return -1;
    }
    return 0;
}

static int nargs_ok(const char *fn, Py_ssize_t nargs, Py_ssize_t want)
{
    if (nargs != want) {
        PyErr_Format(PyExc_TypeError, "%s() takes exactly %zd arguments (%zd given)", fn, want,
                     nargs);
        return 0;
    }
    return 1;
}

PyDoc_STRVAR(step_doc,
"step(p, s, z, restart) -> float\n\n"
"One raw sample z through the filter (kernels.step): s (writable float64\n"
"buffer) is updated in place; restart true re-initialises it first.");

static PyObject *mod_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    Py_buffer pb, sb;
    double z, out;
    int restart;
    (void)self;
    if (!nargs_ok("step", nargs, 4))
        return NULL;
    z = PyFloat_AsDouble(args[2]);
    if (z == -1.0 && PyErr_Occurred())
        return NULL;
    if (args[3] == Py_False || args[3] == Py_None)
        restart = 0;
    else if (args[3] == Py_True)
        restart = 1;
    else if ((restart = PyObject_IsTrue(args[3])) < 0)
        return NULL;
    if (get_ps(args[0], args[1], &pb, &sb) < 0)
        return NULL;
    out = gd_step((const double *)pb.buf, (double *)sb.buf, z, restart);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&pb);
    return PyFloat_FromDouble(out);
}

PyDoc_STRVAR(run_doc,
"run(p, s, z, restarts, out[, trace_index, trace]) -> None\n\n"
"The batch loop (kernels.step over z): out[i] = step(p, s, z[i], restarts[i]).\n"
"z and out are float64 buffers of one length, restarts a bool/uint8 buffer of\n"
"that length or None; s is updated in place. With trace_index and trace (a\n"
"float64 buffer of that length): trace[i] = s[trace_index] after sample i.\n"
"Releases the GIL.");

static PyObject *mod_run(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    Py_buffer pb, sb, zb, rb, ob, tb;
    const unsigned char *r = NULL;
    int have_r = 0;
    Py_ssize_t n, ti = -1;
    (void)self;
    if (nargs != 7 && !nargs_ok("run", nargs, 5))
        return NULL;
    if (nargs == 7) {
        ti = PyLong_AsSsize_t(args[5]);
        if (ti == -1 && PyErr_Occurred())
            return NULL;
    }
    if (get_ps(args[0], args[1], &pb, &sb) < 0)
        return NULL;
    if (get_f64(args[2], &zb, 0, "z") < 0)
        goto fail_ps;
    n = zb.len / 8;
    if (args[3] != Py_None) {
        if (PyObject_GetBuffer(args[3], &rb, PyBUF_FORMAT) < 0)
            goto fail_z;
        have_r = 1;
        if (!is_u8(&rb)) {
            PyErr_Format(PyExc_TypeError, "restarts must hold bool or uint8 items, got format '%s'",
                         rb.format ? rb.format : "B");
            goto fail_r;
        }
        if (rb.len != n) {
            PyErr_Format(PyExc_ValueError, "restarts has %zd items, z has %zd", rb.len, n);
            goto fail_r;
        }
        r = (const unsigned char *)rb.buf;
    }
    if (get_f64(args[4], &ob, 1, "out") < 0)
        goto fail_r;
    if (ob.len / 8 != n) {
        PyErr_Format(PyExc_ValueError, "out has %zd items, z has %zd", ob.len / 8, n);
        PyBuffer_Release(&ob);
        goto fail_r;
    }
    if (nargs == 7) {
        if (ti < 0 || ti >= sb.len / 8) {
            PyErr_Format(PyExc_ValueError, "trace_index %zd is outside the state (%zd values)", ti,
                         sb.len / 8);
            PyBuffer_Release(&ob);
            goto fail_r;
        }
        if (get_f64(args[6], &tb, 1, "trace") < 0) {
            PyBuffer_Release(&ob);
            goto fail_r;
        }
        if (tb.len / 8 != n) {
            PyErr_Format(PyExc_ValueError, "trace has %zd items, z has %zd", tb.len / 8, n);
            PyBuffer_Release(&tb);
            PyBuffer_Release(&ob);
            goto fail_r;
        }
        Py_BEGIN_ALLOW_THREADS
        gd_run_trace((const double *)pb.buf, (double *)sb.buf, (const double *)zb.buf, r,
                     (double *)ob.buf, (long)n, (long)ti, (double *)tb.buf);
        Py_END_ALLOW_THREADS
        PyBuffer_Release(&tb);
    } else {
        Py_BEGIN_ALLOW_THREADS
        gd_run((const double *)pb.buf, (double *)sb.buf, (const double *)zb.buf, r,
               (double *)ob.buf, (long)n);
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&ob);
    if (have_r)
        PyBuffer_Release(&rb);
    PyBuffer_Release(&zb);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&pb);
    Py_RETURN_NONE;
fail_r:
    if (have_r)
        PyBuffer_Release(&rb);
fail_z:
    PyBuffer_Release(&zb);
fail_ps:
    PyBuffer_Release(&sb);
    PyBuffer_Release(&pb);
    return NULL;
}

PyDoc_STRVAR(record_doc,
"record(p, s, z, out, idx, rec) -> None\n\n"
"The batch loop with no restarts (out[i] = step(p, s, z[i], False)) that also\n"
"records rec[j, i] = s[idx[j]] after sample i: idx a float64 buffer of state\n"
"indices (whole numbers), rec a writable float64 buffer of len(idx) x len(z)\n"
"(row-major). s is updated in place. Releases the GIL.");

static PyObject *mod_record(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    Py_buffer pb, sb, zb, ob, ib, rb;
    Py_ssize_t n, m, j, ns;
    long *idx = NULL;
    PyObject *res = NULL;
    (void)self;
    if (!nargs_ok("record", nargs, 6))
        return NULL;
    if (get_ps(args[0], args[1], &pb, &sb) < 0)
        return NULL;
    ns = sb.len / 8;
    if (get_f64(args[2], &zb, 0, "z") < 0)
        goto fail_ps;
    n = zb.len / 8;
    if (get_f64(args[3], &ob, 1, "out") < 0)
        goto fail_z;
    if (get_f64(args[4], &ib, 0, "idx") < 0)
        goto fail_o;
    if (get_f64(args[5], &rb, 1, "rec") < 0)
        goto fail_i;
    m = ib.len / 8;
    if (ob.len / 8 != n || rb.len / 8 != n * m) {
        PyErr_Format(PyExc_ValueError, "out has %zd items and rec %zd, z has %zd and idx %zd",
                     ob.len / 8, rb.len / 8, n, m);
        goto fail_r;
    }
    idx = (long *)PyMem_Malloc((m > 0 ? m : 1) * sizeof(long));
    if (idx == NULL) {
        PyErr_NoMemory();
        goto fail_r;
    }
    for (j = 0; j < m; j++) {
        double v = ((const double *)ib.buf)[j];
        if (!(v >= 0.0 && v < (double)ns && v == (double)(long)v)) {
            PyErr_Format(PyExc_ValueError, "idx[%zd] is not an index of the state (%zd values)", j, ns);
            goto fail_r;
        }
        idx[j] = (long)v;
    }
    Py_BEGIN_ALLOW_THREADS
    gd_run_record((const double *)pb.buf, (double *)sb.buf, (const double *)zb.buf,
                  (double *)ob.buf, (long)n, idx, (long)m, (double *)rb.buf);
    Py_END_ALLOW_THREADS
    Py_INCREF(Py_None);
    res = Py_None;
fail_r:
    PyMem_Free(idx);
    PyBuffer_Release(&rb);
fail_i:
    PyBuffer_Release(&ib);
fail_o:
    PyBuffer_Release(&ob);
fail_z:
    PyBuffer_Release(&zb);
fail_ps:
    PyBuffer_Release(&sb);
    PyBuffer_Release(&pb);
    return res;
}

PyDoc_STRVAR(restart_doc,
"restart(p, s) -> None\n\n"
"Re-initialise the state s in place (kernels.restart; cumulative counters kept).");

static PyObject *mod_restart(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    Py_buffer pb, sb;
    (void)self;
    if (!nargs_ok("restart", nargs, 2))
        return NULL;
    if (get_ps(args[0], args[1], &pb, &sb) < 0)
        return NULL;
    gd_restart((const double *)pb.buf, (double *)sb.buf);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&pb);
    Py_RETURN_NONE;
}

PyDoc_STRVAR(layout_total_doc,
"layout_total(n) -> int\n\nLength of the state buffer for AR order n (kernels.layout(n)[6]).");

static PyObject *mod_butter_sos(PyObject *self, PyObject *args)
{
    int order, i, j, nsec;
    double fc, fs, p[N_PARAMS];
    PyObject *out;
    (void)self;
    if (!PyArg_ParseTuple(args, "idd", &order, &fc, &fs))
        return NULL;
    if (order < 1 || order > 2 * MAX_SOS) {
        PyErr_Format(PyExc_ValueError, "order must be in 1..%d, got %d", 2 * MAX_SOS, order);
        return NULL;
    }
    nsec = gd_butter_sos(order, fc, fs, p);
    out = PyList_New(nsec);
    for (i = 0; out != NULL && i < nsec; i++) {
        PyObject *sec = PyTuple_New(5);
        if (sec == NULL) {
            Py_CLEAR(out);
            break;
        }
        for (j = 0; j < 5; j++) {
            PyObject *v = PyFloat_FromDouble(p[P_SOS + 5 * i + j]);
            if (v == NULL || PyTuple_SetItem(sec, j, v) < 0) {   /* SetItem steals v */
                Py_DECREF(sec);
                Py_CLEAR(out);
                break;
            }
        }
        if (out == NULL || PyList_SetItem(out, i, sec) < 0) {   /* steals sec */
            Py_CLEAR(out);
            break;
        }
    }
    return out;
}

static PyObject *mod_layout_total(PyObject *self, PyObject *arg)
{
    long n = PyLong_AsLong(arg);
    (void)self;
    if (n == -1 && PyErr_Occurred())
        return NULL;
    if (n < 0 || n > GD_MAX_ORDER) {
        PyErr_Format(PyExc_ValueError, "n must be in 0..%d, got %ld", GD_MAX_ORDER, n);
        return NULL;
    }
    return PyLong_FromLong(gd_layout_total((int)n));
}

/* ---------------------------------------------------------- simulated gyro */
#define SIM_CARD_LEN_V1 GD_SIM_CARD_LEN_V1 /* before the angle Gauss-Markov term */
#define SIM_CARD_LEN GD_SIM_CARD_LEN       /* + n_agm, agm_sigma, agm_tau */

/* a card vector (simkernels.card_vector) into c; -1 with an exception if malformed */
static int get_card(PyObject *obj, gd_card_t *c)
{
    Py_buffer b;
    const double *v;
    int M = GD_SIM_MAX_REPEAT;
    if (get_f64(obj, &b, 0, "card") < 0)
        return -1;
    v = (const double *)b.buf;
    if ((b.len / 8 != SIM_CARD_LEN && b.len / 8 != SIM_CARD_LEN_V1) || !(v[0] > 0) || !(v[10] >= 0 && v[10] <= M && v[10] == (int)v[10])
        || !(v[11] >= 0 && v[11] <= M && v[11] == (int)v[11])) {
        PyErr_Format(PyExc_ValueError, "card must be a card vector of %d (or %d) float64 "
                     "(simkernels.card_vector)", SIM_CARD_LEN, SIM_CARD_LEN_V1);
        PyBuffer_Release(&b);
        return -1;
    }
    if (b.len / 8 == SIM_CARD_LEN) {
        const double *a = v + SIM_CARD_LEN_V1;
        if (!(a[0] >= 0 && a[0] <= M && a[0] == (int)a[0])) {
            PyErr_SetString(PyExc_ValueError, "card vector: n_agm must be a whole number in 0..16");
            PyBuffer_Release(&b);
            return -1;
        }
    }
    gd_sim_card_from_vector(v, (int)(b.len / 8), c);
    PyBuffer_Release(&b);
    return 0;
}

/* p and s of the simulator, checked against each other (s may be NULL) */
static int get_sim_ps(PyObject *po, PyObject *so, Py_buffer *pb, Py_buffer *sb)
{
    const double *p;
    double nb, ns, na;
    if (get_f64(po, pb, 0, "p") < 0)
        return -1;
    p = (const double *)pb->buf;
    nb = pb->len / 8 >= PS_BANK ? p[PS_NBANK] : -1;
    ns = pb->len / 8 >= PS_BANK ? p[PS_NSIN] : -1;
    if (!(nb >= 0 && nb <= 1000 && nb == (long)nb && ns >= 0 && ns <= GD_SIM_MAX_REPEAT && ns == (long)ns)
        || pb->len / 8 < PS_BANK + 3 * (long)nb + 3 * (long)ns + 1) {
        PyErr_SetString(PyExc_ValueError, "p is not a simulator parameter buffer (sim_params)");
        PyBuffer_Release(pb);
        return -1;
    }
    na = p[PS_BANK + 3 * (long)nb + 3 * (long)ns];   /* angle Gauss-Markov count, its terms follow */
    if (!(na >= 0 && na <= GD_SIM_MAX_REPEAT && na == (long)na)
        || pb->len / 8 < PS_BANK + 3 * (long)nb + 3 * (long)ns + 1 + 3 * (long)na) {
        PyErr_SetString(PyExc_ValueError, "p is not a simulator parameter buffer (sim_params)");
        PyBuffer_Release(pb);
        return -1;
    }
    if (so == NULL)
        return 0;
    if (get_f64(so, sb, 1, "s") < 0) {
        PyBuffer_Release(pb);
        return -1;
    }
    if (sb->len / 8 != gd_sim_n_state(p)) {
        PyErr_Format(PyExc_ValueError, "s has %zd items, the simulator needs %d", sb->len / 8,
                     gd_sim_n_state(p));
        PyBuffer_Release(sb);
        PyBuffer_Release(pb);
        return -1;
    }
    return 0;
}

static PyObject *mod_sim_n_params(PyObject *self, PyObject *arg)
{
    gd_card_t c;
    (void)self;
    if (get_card(arg, &c) < 0)
        return NULL;
    return PyLong_FromLong(gd_sim_n_params(&c));
}

static PyObject *mod_sim_params(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    gd_card_t c;
    Py_buffer pb;
    double seed;
    (void)self;
    if (!nargs_ok("sim_params", nargs, 3) || get_card(args[0], &c) < 0)
        return NULL;
    seed = PyFloat_AsDouble(args[1]);
    if (seed == -1.0 && PyErr_Occurred())
        return NULL;
    if (!(seed >= 0 && seed < 9007199254740992.0 && seed == (double)(long long)seed)) {
        PyErr_Format(PyExc_ValueError, "seed must be an integer in 0..2**53-1, got %g", seed);
        return NULL;
    }
    if (get_f64(args[2], &pb, 1, "p") < 0)
        return NULL;
    if (pb.len / 8 != gd_sim_n_params(&c)) {
        PyErr_Format(PyExc_ValueError, "p has %zd items, the card needs %d", pb.len / 8,
                     gd_sim_n_params(&c));
        PyBuffer_Release(&pb);
        return NULL;
    }
    gd_sim_params(&c, seed, (double *)pb.buf);
    PyBuffer_Release(&pb);
    Py_RETURN_NONE;
}

static PyObject *mod_sim_n_state(PyObject *self, PyObject *arg)
{
    Py_buffer pb;
    long n;
    (void)self;
    if (get_sim_ps(arg, NULL, &pb, NULL) < 0)
        return NULL;
    n = gd_sim_n_state((const double *)pb.buf);
    PyBuffer_Release(&pb);
    return PyLong_FromLong(n);
}

static PyObject *mod_sim_reset(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    Py_buffer pb, sb;
    (void)self;
    if (!nargs_ok("sim_reset", nargs, 2) || get_sim_ps(args[0], args[1], &pb, &sb) < 0)
        return NULL;
    gd_sim_reset((const double *)pb.buf, (double *)sb.buf);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&pb);
    Py_RETURN_NONE;
}

static PyObject *mod_sim_run(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    Py_buffer pb, sb, tb, rb, ob;
    int have_t = 0, have_r = 0;
    const double *t = NULL;
    const unsigned char *r = NULL;
    Py_ssize_t n;
    PyObject *ret = NULL;
    (void)self;
    if (!nargs_ok("sim_run", nargs, 5) || get_sim_ps(args[0], args[1], &pb, &sb) < 0)
        return NULL;
    if (get_f64(args[4], &ob, 1, "out") < 0)
        goto done_ps;
    n = ob.len / 8;
    if (args[2] != Py_None) {
        if (get_f64(args[2], &tb, 0, "truth") < 0)
            goto done_o;
        have_t = 1;
        if (tb.len / 8 != n) {
            PyErr_Format(PyExc_ValueError, "truth has %zd items, out has %zd", tb.len / 8, n);
            goto done_t;
        }
        t = (const double *)tb.buf;
    }
    if (args[3] != Py_None) {
        if (PyObject_GetBuffer(args[3], &rb, PyBUF_FORMAT) < 0)
            goto done_t;
        have_r = 1;
        if (!is_u8(&rb) || rb.len != n) {
            PyErr_Format(PyExc_ValueError, "restarts must be %zd bool/uint8 items", n);
            goto done_r;
        }
        r = (const unsigned char *)rb.buf;
    }
    Py_BEGIN_ALLOW_THREADS
    gd_sim_run((const double *)pb.buf, (double *)sb.buf, (long)n, t, r, (double *)ob.buf);
    Py_END_ALLOW_THREADS
    ret = Py_None;
    Py_INCREF(ret);
done_r:
    if (have_r)
        PyBuffer_Release(&rb);
done_t:
    if (have_t)
        PyBuffer_Release(&tb);
done_o:
    PyBuffer_Release(&ob);
done_ps:
    PyBuffer_Release(&sb);
    PyBuffer_Release(&pb);
    return ret;
}

static PyMethodDef methods[] = {
    {"step", (PyCFunction)(void (*)(void))mod_step, METH_FASTCALL, step_doc},
    {"run", (PyCFunction)(void (*)(void))mod_run, METH_FASTCALL, run_doc},
    {"record", (PyCFunction)(void (*)(void))mod_record, METH_FASTCALL, record_doc},
    {"restart", (PyCFunction)(void (*)(void))mod_restart, METH_FASTCALL, restart_doc},
    {"layout_total", mod_layout_total, METH_O, layout_total_doc},
    {"butter_sos", mod_butter_sos, METH_VARARGS,
     "butter_sos(order, cutoff_hz, fs) -> [(b0, b1, b2, a1, a2)] (gdcore.c gd_butter_sos, as kernels.butter_sos)"},
    {"sim_n_params", mod_sim_n_params, METH_O, "sim_n_params(card) -> int (gdsim.c)"},
    {"sim_params", (PyCFunction)(void (*)(void))mod_sim_params, METH_FASTCALL,
     "sim_params(card, seed, p): fill p from a card vector and a seed (gdsim.c)"},
    {"sim_n_state", mod_sim_n_state, METH_O, "sim_n_state(p) -> int (gdsim.c)"},
    {"sim_reset", (PyCFunction)(void (*)(void))mod_sim_reset, METH_FASTCALL,
     "sim_reset(p, s): the simulator state at the start (gdsim.c)"},
    {"sim_run", (PyCFunction)(void (*)(void))mod_sim_run, METH_FASTCALL,
     "sim_run(p, s, truth, restarts, out): measured samples into out, s updated (gdsim.c); "
     "truth float64 or None, restarts bool/uint8 or None"},
    {NULL, NULL, 0, NULL},
};

#define C(name) {#name, (double)(name)}
static const struct {
    const char *name;
    double value;
} constants[] = {
    C(P_ORDER), C(P_METHOD), C(P_LAM), C(P_B), C(P_GAMMA), C(P_Q0), C(P_R0), C(P_P0_RLS),
    C(P_P0_KF), C(P_WARMUP), C(P_R_FLOOR), C(P_OUTLIER_SIGMA), C(P_OUTLIER_RUN), C(P_LP_NSEC),
    C(P_LP_CUTOFF), C(P_SOS), C(MAX_SOS), C(P_MO_NF), C(P_MO_FADE), C(P_MO_BR), C(P_MO_RESET),
    C(P_MO_NLAG), C(P_MO_HUBER), C(P_MO_KAPPA), C(P_MO_CLIP2), C(P_MO_VAR), C(P_MO_G), C(P_MO_RFIX), C(P_MO_SPEC), C(P_MO_SBB), C(P_MO_SRATIO), C(P_MO_COS),
    C(MO_SPEC_N), C(MO_SPEC_K0), C(MO_SPEC_NB), C(MO_SPEC_RANK), C(MO_HI_J0), C(MO_HI_NB), C(MO_LINE_J0), C(MO_MAX_NF), C(MO_MAX_NLAG),
    C(N_PARAMS), C(P_FS), C(P_OE_MIN), C(P_OE_BETA), C(P_OE_DCUT), C(OE_X), C(OE_DX), C(OE_ZP), C(S_K), C(S_KD), C(S_R), C(S_Q), C(S_S2), C(S_NS2),
    C(S_CONV), C(S_INNOV), C(S_SVAR), C(S_NRESET), C(S_OUT), C(S_RLS_ERR), C(S_BK), C(S_NREJ),
    C(S_REJRUN), C(S_NREOPEN), C(S_ZREF), C(S_LO), C(S_HI), C(S_HOLD), C(S_NCLAMP),
    C(S_NHEAL), C(N_HEADER), C(N_EXT), C(M_R), C(M_BK), C(M_HPOS), C(M_ANG), C(M_NW), C(M_BEST), C(M_PVAR),
    C(M_MABS), C(M_HIST), C(M_BANK), C(M_LPD), C(M_SPOS), C(M_SR), C(M_SBK), C(M_SBAD), C(M_SFOLD), C(M_GEFF), C(M_NWC), C(M_LRAT), C(M_LON), C(M_CUS), C(P_MO_PT), C(P_MO_LINE), C(P_MO_CUS), C(P_MO_NCA), C(P_MO_SPECH), C(M_SRH), C(M_SBKH), C(M_GRD), C(M_BIAS), C(GB_N), C(GB_LANE), C(P_BIAS), C(P_BIAS_LANE), C(P_BIAS_NEED), C(P_BIAS_CAP), C(P_BIAS_FLOOR), C(P_BIAS_NAVR), C(CA_NEWTON_STEPS), C(MAX_MOTION_ORDER),
};
#undef C

/* the methods' ids, METHOD_<NAME> (floats in kernels.py), from the registry's gdmethods.h */
#define M(name, id) {#id, id},
static const struct {
    const char *name;
    double value;
} method_ids[] = {GD_METHODS(M)};
#undef M

static int exec_module(PyObject *m)
{
    size_t i;
    PyObject *d = PyDict_New();
    if (d == NULL)
        return -1;
    for (i = 0; i < sizeof constants / sizeof constants[0]; i++) {
        PyObject *o = PyLong_FromDouble(constants[i].value);
        if (o == NULL || PyDict_SetItemString(d, constants[i].name, o) < 0) {
            Py_XDECREF(o);
            Py_DECREF(d);
            return -1;
        }
        Py_DECREF(o);
    }
    for (i = 0; i < sizeof method_ids / sizeof method_ids[0]; i++) {
        PyObject *o = PyFloat_FromDouble(method_ids[i].value);
        if (o == NULL || PyDict_SetItemString(d, method_ids[i].name, o) < 0) {
            Py_XDECREF(o);
            Py_DECREF(d);
            return -1;
        }
        Py_DECREF(o);
    }
    if (PyModule_AddObject(m, "CONSTANTS", d) < 0) {
        Py_DECREF(d);
        return -1;
    }
    return 0;
}

static PyModuleDef_Slot slots[] = {
    {Py_mod_exec, exec_module},
    {0, NULL},
};

static struct PyModuleDef moduledef = {
    PyModuleDef_HEAD_INIT,
    "gyrodenoise._gdcore",
    "The per-sample filter kernels of gyrodenoise.core.kernels, compiled from gyrodenoise/core/gdcore.c.",
    0,
    methods,
    slots,
    NULL,
    NULL,
    NULL,
};

PyMODINIT_FUNC PyInit__gdcore(void)
{
    return PyModuleDef_Init(&moduledef);
}
