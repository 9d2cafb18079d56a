/* The acoustic channel's per-reception work in C (aquasim_py/channel/acoustic.py is the
 * reference and the fallback: AcousticChannel.compiled_delivery = False runs it).
 *
 * Core: every node's channel-side state in contiguous memory, owned by one AcousticChannel:
 *   - own transmissions (start, end) and busy_until (the Python _Modem.tx_start / tx_end /
 *     busy_until, pruned as AcousticChannel._prune prunes them);
 *   - the signal log (arrival, end, SNR, transmission uid), sorted by arrival and pruned as
 *     _Modem.record prunes it;
 *   - the affine clock (1 + skew, offset) of nodes whose stamp is exact (_NodeCore.exact_stamp).
 * Core.start records one transmission's signals at every receiver (AcousticChannel._start's
 * loop) and queues its Deliveries entry; Core.run is the entry's callback and mirrors
 * AcousticChannel._next_delivery (with _scan): verdict, stamp, delivery to the node (a Python
 * call: the node side stays Python), packets row, next entry, and the drain of consecutive
 * channel entries while they come next in SimPy's order.
 *
 * The entries wait on the channel's own heap (own_heap; AcousticChannel.compiled_heap), keyed
 * (time, sequence number) with the sequence number drawn from SimPy's counter exactly where
 * the Python path draws it. Only the head is also on SimPy's queue, as the tuple SimPy would
 * hold for it (time, NORMAL, its own sequence number, entry): SimPy pops it exactly when it
 * would have popped that entry had every entry been on its queue, and every other entry of the
 * channel comes after it, so the order of events is the Python path's. Without own_heap every
 * entry goes on SimPy's queue through heapq's own functions, as in Python.
 *
 * Every float expression is the Python one in the same order (built with -ffp-contract=off:
 * no fused multiply-add), so the rows have the same bits.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <structmember.h>
#include <math.h>
#include <string.h>

#include "../_events.h"

/* the kernel's compiled event queue (aquasim_py/_events.c), when built: NULL otherwise */
static AquasimEventsAPI *events_api;

/* ------------------------------------------------------------------------------------------ */
/* interned strings and heapq */

static PyObject *s_rx, *s_drop, *s_half_duplex, *s_collision, *s_now;
static PyObject *s_uid, *s_src, *s_kind, *s_bits;
static PyObject *heappush_fn, *heappop_fn;

/* ------------------------------------------------------------------------------------------ */
/* per-node state, laid out for the delivery: a node is one cache line, a signal half of one */

typedef struct {
    double arr, end, snr; /* arrival and end (true s), SNR (dB) */
    long long uid;        /* the transmission ("e is not sig": one signal per transmission here) */
} Sig;

typedef struct {
    double start, end;    /* an own transmission (true s) */
} Tx;

typedef struct {
    double busy_until;    /* latest end of own transmissions (true s) */
    Sig *sig;             /* the signal log, sorted by arrival */
    Tx *tx;               /* own transmissions in order of start; room for log_cap + 1 */
    PyObject *deliver;    /* the port's deliver(pkt, rx_local, snr, pressure), or the port tagged (PORT) */
    double a, b;          /* exact clock: local = a * t + b with a = 1.0 + skew; a = 0: not exact */
    int32_t nsig, capsig, ntx, log_cap;
} Node;

/* Node.deliver holds the port itself, tagged in its low bit, when the port's deliver is the
 * core's deliver_fn bound to it (every _NodeCore's is): the call then passes the port as the
 * function's first argument, and the bound method object, one more cold line per delivery in a
 * large network, is not kept. Any other deliver callable is kept as it is, untagged. */
#define PORT ((uintptr_t)1)
static inline PyObject *untag(PyObject *o) { return (PyObject *)((uintptr_t)o & ~PORT); }

static int grow(void **p, Py_ssize_t cap, size_t size) {
    void *q = PyMem_Realloc(*p, (size_t)cap * size);
    if (q == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    *p = q;
    return 0;
}

/* bisect.bisect_left / bisect_right on the arrivals of a signal log, bisect_left on the starts
 * of a transmission log */
static Py_ssize_t sig_left(const Sig *a, Py_ssize_t n, double x) {
    Py_ssize_t lo = 0, hi = n;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        if (a[mid].arr < x) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

static Py_ssize_t sig_right(const Sig *a, Py_ssize_t n, double x) {
    Py_ssize_t lo = 0, hi = n;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        if (x < a[mid].arr) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

static Py_ssize_t tx_left(const Tx *a, Py_ssize_t n, double x) {
    Py_ssize_t lo = 0, hi = n;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        if (a[mid].start < x) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

/* ------------------------------------------------------------------------------------------ */
/* Links: the heard receivers of one transmission, packed (sorted by delay, as _links gives them) */

typedef struct {
    double tof, snr;      /* delay (s), SNR (dB) */
    Py_ssize_t rid;       /* receiver */
    PyObject *path;       /* path name (one of a few interned strings) */
} Heard;

typedef struct {
    PyObject_HEAD
    Py_ssize_t n;
    Heard *h;
} Links;

static void Links_dealloc(Links *self) {
    for (Py_ssize_t i = 0; i < self->n; i++) {
        Py_XDECREF(self->h[i].path);
    }
    PyMem_Free(self->h);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyTypeObject LinksType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "aquasim_py.channel._delivery.Links",
    .tp_basicsize = sizeof(Links),
    .tp_dealloc = (destructor)Links_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "the heard receivers of one transmission, packed (Core.pack)",
};

/* ------------------------------------------------------------------------------------------ */
/* Core */

typedef struct Deliveries Deliveries;

/* an entry of the channel's own heap: SimPy's key (time, NORMAL, eid) less the constant priority */
typedef struct {
    double t;
    long long eid;
    Deliveries *d;
} HEnt;

typedef struct {
    PyObject_HEAD
    Node *nodes;
    Py_ssize_t n, cap;
    double max_duration;   /* the channel's longest packet so far (s), kept in step by Python */
    int collision;         /* 0 none, 1 destructive, 2 capture */
    int drain;             /* AcousticChannel.drain_deliveries */
    int jitter;            /* jitter_std_s > 0: every stamp through Python */
    double capture_db;
    PyObject *queue;       /* SimPy's heap (list) */
    PyObject *eid;         /* SimPy's sequence counter */
    PyObject *env;
    PyObject *priority;    /* simpy.events.NORMAL */
    PyObject *rows;        /* the packets row buffer (list) */
    PyObject *stamp;       /* stamp(rid, t) -> local s, for clocks that are not exact or with jitter */
    PyObject *pressure;    /* pressure(pkt, rid, t_send, t_arr) -> float */
    PyObject *pressure_kind;
    PyObject *cb;          /* [self.run]: the callbacks of every channel entry */
    PyObject *deliver_fn;  /* the function of the first node's bound deliver (see PORT) */
    PyObject *nan;
    int own_heap;          /* the channel's entries on its own heap, its head proxied on SimPy's */
    int cq;                /* queue is the kernel's compiled queue (events_api): entries go on it */
    long prio;             /* the value of `priority` */
    HEnt *heap;
    Py_ssize_t hn, hcap;
} Core;

struct Deliveries {
    /* what a delivery reads comes first: the object's first 144 bytes (two or three lines;
     * the compiled queue prefetches three when this entry becomes its head) */
    PyObject_HEAD
    PyObject *callbacks;   /* what Environment.step reads and clears */
    Core *core;
    const Heard *hs;       /* links->h, kept here: the Links object is one more cold line */
    Py_ssize_t k, n;       /* next delivery, one past the last */
    Heard cur;             /* links->h[k], copied when k was queued: the delivery reads only d */
    double t0, duration;
    PyObject *src_o, *uid_o, *dst_o, *kind, *bits; /* the rows' fields */
    long long uid;         /* the transmission, as the signal logs name it */
    int pressure;          /* the packet is a sound emission (kind == pressure_kind) */
    int proxied;           /* own heap: this entry is also on SimPy's queue, with the same key */
    PyObject *pkt;
    Links *links;
    double at;             /* own heap: the entry's key (time, eid) */
    PyObject *eid;
};

static PyTypeObject CoreType;
static PyTypeObject DeliveriesType;

static int Core_traverse(Core *self, visitproc visit, void *arg) {
    for (Py_ssize_t i = 0; i < self->n; i++) Py_VISIT(untag(self->nodes[i].deliver));
    Py_VISIT(self->deliver_fn);
    Py_VISIT(self->queue);
    Py_VISIT(self->eid);
    Py_VISIT(self->env);
    Py_VISIT(self->rows);
    Py_VISIT(self->stamp);
    Py_VISIT(self->pressure);
    Py_VISIT(self->cb);
    for (Py_ssize_t i = 0; i < self->hn; i++) Py_VISIT(self->heap[i].d);
    return 0;
}

static int Core_clear(Core *self) {
    for (Py_ssize_t i = 0; i < self->n; i++) {
        PyObject *o = untag(self->nodes[i].deliver);
        self->nodes[i].deliver = NULL;
        Py_XDECREF(o);
    }
    Py_CLEAR(self->deliver_fn);
    Py_CLEAR(self->queue);
    Py_CLEAR(self->eid);
    Py_CLEAR(self->env);
    Py_CLEAR(self->priority);
    Py_CLEAR(self->rows);
    Py_CLEAR(self->stamp);
    Py_CLEAR(self->pressure);
    Py_CLEAR(self->pressure_kind);
    Py_CLEAR(self->cb);
    Py_ssize_t hn = self->hn;
    self->hn = 0;
    for (Py_ssize_t i = 0; i < hn; i++) Py_CLEAR(self->heap[i].d);
    return 0;
}

static void Core_dealloc(Core *self) {
    PyObject_GC_UnTrack(self);
    Core_clear(self);
    for (Py_ssize_t i = 0; i < self->n; i++) {
        PyMem_Free(self->nodes[i].sig);
        PyMem_Free(self->nodes[i].tx);
    }
    PyMem_Free(self->nodes);
    PyMem_Free(self->heap);
    Py_XDECREF(self->nan);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int Core_init(Core *self, PyObject *args, PyObject *kwds) {
    static char *kw[] = {"env", "queue", "eid", "priority", "rows", "collision", "capture_threshold_db",
                         "jitter", "stamp", "pressure", "pressure_kind", "drain", "own_heap", NULL};
    PyObject *env, *queue, *eid, *priority, *rows, *stamp, *pressure, *pressure_kind;
    const char *collision;
    double capture;
    int jitter, drain, own_heap;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "OOOOO!sdpOOOpp", kw, &env, &queue, &eid, &priority,
                                     &PyList_Type, &rows, &collision, &capture, &jitter, &stamp, &pressure,
                                     &pressure_kind, &drain, &own_heap))
        return -1;
    if (self->cb != NULL) {
        PyErr_SetString(PyExc_TypeError, "Core: already initialized");
        return -1;
    }
    long prio = PyLong_AsLong(priority);
    if (prio == -1 && PyErr_Occurred()) return -1;
    int cq = events_api != NULL && Py_IS_TYPE(queue, events_api->QueueType);
    if (!cq && !PyList_Check(queue)) {
        PyErr_SetString(PyExc_TypeError, "Core: queue must be SimPy's list heap or the kernel's compiled queue");
        return -1;
    }
    if (strcmp(collision, "none") == 0) self->collision = 0;
    else if (strcmp(collision, "destructive") == 0) self->collision = 1;
    else if (strcmp(collision, "capture") == 0) self->collision = 2;
    else {
        PyErr_Format(PyExc_ValueError, "Core: unknown collision model %s", collision);
        return -1;
    }
    Core_clear(self);
    Py_INCREF(env); self->env = env;
    Py_INCREF(queue); self->queue = queue;
    Py_INCREF(eid); self->eid = eid;
    Py_INCREF(priority); self->priority = priority;
    Py_INCREF(rows); self->rows = rows;
    Py_INCREF(stamp); self->stamp = stamp;
    Py_INCREF(pressure); self->pressure = pressure;
    Py_INCREF(pressure_kind); self->pressure_kind = pressure_kind;
    self->capture_db = capture;
    self->jitter = jitter;
    self->drain = drain;
    self->cq = cq;
    self->own_heap = own_heap && !cq; /* the compiled queue keeps its keys contiguous itself */
    self->prio = prio;
    if (self->nan == NULL && (self->nan = PyFloat_FromDouble(Py_NAN)) == NULL) return -1;
    PyObject *run = PyObject_GetAttrString((PyObject *)self, "run");
    if (run == NULL) return -1;
    self->cb = PyList_New(1);
    if (self->cb == NULL) {
        Py_DECREF(run);
        return -1;
    }
    PyList_SET_ITEM(self->cb, 0, run);
    return 0;
}

/* attach(deliver, exact, skew, offset): the next node (ids 0, 1, ... in order) */
static PyObject *Core_attach(Core *self, PyObject *args) {
    PyObject *deliver;
    int exact;
    double skew, offset;
    if (!PyArg_ParseTuple(args, "Opdd", &deliver, &exact, &skew, &offset)) return NULL;
    if (self->n == self->cap) {
        Py_ssize_t cap = self->cap ? 2 * self->cap : 64;
        if (grow((void **)&self->nodes, cap, sizeof(Node)) < 0) return NULL;
        self->cap = cap;
    }
    Tx *tx = PyMem_Malloc(9 * sizeof(Tx));
    if (tx == NULL) return PyErr_NoMemory();
    Node *nd = &self->nodes[self->n];
    memset(nd, 0, sizeof(Node));
    nd->busy_until = -Py_HUGE_VAL;
    nd->a = exact ? 1.0 + skew : 0.0; /* _NodeCore.clock_stamp's (1.0 + c.skew): the same double */
    nd->b = offset;
    nd->tx = tx;
    nd->log_cap = 8;
    if (PyMethod_Check(deliver)) {
        PyObject *fn = PyMethod_GET_FUNCTION(deliver), *port = PyMethod_GET_SELF(deliver);
        if (self->deliver_fn == NULL) {
            Py_INCREF(fn);
            self->deliver_fn = fn;
        }
        if (fn == self->deliver_fn) {
            Py_INCREF(port);
            nd->deliver = (PyObject *)((uintptr_t)port | PORT);
        }
    }
    if (nd->deliver == NULL) {
        Py_INCREF(deliver);
        nd->deliver = deliver;
    }
    self->n++;
    Py_RETURN_NONE;
}

static Node *node_at(Core *self, Py_ssize_t i) {
    if (i < 0 || i >= self->n) {
        PyErr_Format(PyExc_IndexError, "no node %zd on this channel", i);
        return NULL;
    }
    return &self->nodes[i];
}

/* transmit(node, start, end, now): an own transmission [start, end) (true s), as
 * AcousticChannel._start appends it, then _prune when the log exceeds its cap */
static PyObject *Core_transmit(Core *self, PyObject *args) {
    Py_ssize_t i;
    double start, end, now;
    if (!PyArg_ParseTuple(args, "nddd", &i, &start, &end, &now)) return NULL;
    Node *nd = node_at(self, i);
    if (nd == NULL) return NULL;
    nd->tx[nd->ntx].start = start; /* room: ntx <= log_cap here */
    nd->tx[nd->ntx].end = end;
    nd->ntx++;
    if (end > nd->busy_until) nd->busy_until = end;
    if (nd->ntx > nd->log_cap) {
        /* _prune: keep the transmissions that ended at or after now - longest packet */
        double cutoff = now - self->max_duration;
        int32_t k = 0;
        for (int32_t j = 0; j < nd->ntx; j++)
            if (nd->tx[j].end >= cutoff) nd->tx[k++] = nd->tx[j];
        nd->ntx = k;
        int32_t cap = 2 * k > 8 ? 2 * k : 8;
        if (cap != nd->log_cap) {
            if (grow((void **)&nd->tx, cap + 1, sizeof(Tx)) < 0) return NULL;
            nd->log_cap = cap;
        }
    }
    Py_RETURN_NONE;
}

/* _Modem.record: forget the signals that arrived before `forget`, then insert after equal arrivals */
static int record(Node *nd, double arr, double end, double snr, long long uid, double forget) {
    if (nd->nsig && nd->sig[0].arr < forget) {
        Py_ssize_t j = sig_left(nd->sig, nd->nsig, forget);
        memmove(nd->sig, nd->sig + j, (nd->nsig - j) * sizeof(Sig));
        nd->nsig -= (int32_t)j;
    }
    if (nd->nsig == nd->capsig) {
        if (nd->capsig > INT32_MAX / 2) {
            PyErr_NoMemory();
            return -1;
        }
        int32_t cap = nd->capsig ? 2 * nd->capsig : 16;
        if (grow((void **)&nd->sig, cap, sizeof(Sig)) < 0) return -1;
        nd->capsig = cap;
    }
    Py_ssize_t j = sig_right(nd->sig, nd->nsig, arr);
    memmove(nd->sig + j + 1, nd->sig + j, (nd->nsig - j) * sizeof(Sig));
    nd->sig[j] = (Sig){arr, end, snr, uid};
    nd->nsig++;
    return 0;
}

/* pack(heard): heard as _links gives it, [(receiver id, delay, path name, snr), ...] sorted by delay */
static PyObject *Core_pack(Core *self, PyObject *heard) {
    if (!PyList_Check(heard)) {
        PyErr_SetString(PyExc_TypeError, "pack: heard must be a list");
        return NULL;
    }
    Py_ssize_t n = PyList_GET_SIZE(heard);
    Links *L = PyObject_New(Links, &LinksType);
    if (L == NULL) return NULL;
    L->n = 0;
    L->h = PyMem_Malloc((n ? n : 1) * sizeof(Heard));
    if (L->h == NULL) {
        Py_DECREF(L);
        return PyErr_NoMemory();
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *h = PyList_GET_ITEM(heard, i);
        if (!PyTuple_Check(h) || PyTuple_GET_SIZE(h) != 4) {
            Py_DECREF(L);
            PyErr_SetString(PyExc_TypeError, "pack: heard entries are (receiver id, delay, path, snr)");
            return NULL;
        }
        Py_ssize_t rid = PyLong_AsSsize_t(PyTuple_GET_ITEM(h, 0));
        if (rid == -1 && PyErr_Occurred()) {
            Py_DECREF(L);
            return NULL;
        }
        if (rid < 0 || rid >= self->n) {
            Py_DECREF(L);
            PyErr_Format(PyExc_IndexError, "pack: no node %zd on this channel", rid);
            return NULL;
        }
        PyObject *t = PyTuple_GET_ITEM(h, 1), *s = PyTuple_GET_ITEM(h, 3);
        double tv = PyFloat_AsDouble(t), sv = PyFloat_AsDouble(s);
        if (PyErr_Occurred()) {
            Py_DECREF(L);
            return NULL;
        }
        PyObject *path = PyTuple_GET_ITEM(h, 2);
        Py_INCREF(path);
        L->h[i] = (Heard){tv, sv, rid, path};
        L->n = i + 1;
    }
    return (PyObject *)L;
}

/* heappush(SimPy's queue, (at, NORMAL, eid, d)) */
static int push_simpy(Core *self, Deliveries *d, PyObject *t, PyObject *eid) {
    PyObject *entry = PyTuple_New(4);
    if (entry == NULL) return -1;
    Py_INCREF(t);
    Py_INCREF(self->priority);
    Py_INCREF(eid);
    Py_INCREF(d);
    PyTuple_SET_ITEM(entry, 0, t);
    PyTuple_SET_ITEM(entry, 1, self->priority);
    PyTuple_SET_ITEM(entry, 2, eid);
    PyTuple_SET_ITEM(entry, 3, (PyObject *)d);
    PyObject *argv[2] = {self->queue, entry};
    PyObject *r = PyObject_Vectorcall(heappush_fn, argv, 2, NULL);
    Py_DECREF(entry);
    if (r == NULL) return -1;
    Py_DECREF(r);
    return 0;
}

static int hless(const HEnt *a, const HEnt *b) { return a->t < b->t || (a->t == b->t && a->eid < b->eid); }

/* the own heap's push and pop (the entry's reference moves in and out) */
static int heap_push(Core *self, HEnt e) {
    if (self->hn == self->hcap) {
        Py_ssize_t cap = self->hcap ? 2 * self->hcap : 256;
        if (grow((void **)&self->heap, cap, sizeof(HEnt)) < 0) return -1;
        self->hcap = cap;
    }
    HEnt *h = self->heap;
    Py_ssize_t pos = self->hn++;
    while (pos > 0) {
        Py_ssize_t parent = (pos - 1) >> 1;
        if (!hless(&e, &h[parent])) break;
        h[pos] = h[parent];
        pos = parent;
    }
    h[pos] = e;
    return 0;
}

static Deliveries *heap_pop(Core *self) {
    HEnt *h = self->heap;
    Deliveries *top = h[0].d;
    HEnt last = h[--self->hn];
    Py_ssize_t n = self->hn, pos = 0;
    if (n > 0) {
        for (;;) {
            Py_ssize_t c = 2 * pos + 1;
            if (c >= n) break;
            if (c + 1 < n && hless(&h[c + 1], &h[c])) c++;
            if (!hless(&h[c], &last)) break;
            h[pos] = h[c];
            pos = c;
        }
        h[pos] = last;
    }
    return top;
}

/* queue d's next delivery at true time `at` with the next sequence number, as
 * Environment.schedule would (priority NORMAL): on SimPy's heap, or on the own heap */
static int push(Core *self, Deliveries *d, double at) {
    if (self->cq) return events_api->push(self->queue, at, self->prio, (PyObject *)d);
    PyObject *eid = PyIter_Next(self->eid);
    if (eid == NULL) {
        if (!PyErr_Occurred()) PyErr_SetString(PyExc_RuntimeError, "SimPy's event counter ended");
        return -1;
    }
    if (self->own_heap) {
        long long eid_v = PyLong_AsLongLong(eid);
        if (eid_v == -1 && PyErr_Occurred()) {
            Py_DECREF(eid);
            return -1;
        }
        Py_XSETREF(d->eid, eid);
        d->at = at;
        HEnt e = {at, eid_v, d};
        if (heap_push(self, e) < 0) return -1;
        Py_INCREF(d);
        return 0;
    }
    PyObject *t = PyFloat_FromDouble(at);
    if (t == NULL) {
        Py_DECREF(eid);
        return -1;
    }
    int rc = push_simpy(self, d, t, eid);
    Py_DECREF(t);
    Py_DECREF(eid);
    return rc;
}

/* own heap: the head is on SimPy's queue too, with its own key (time, NORMAL, eid), so SimPy
 * pops it exactly when it would have popped that entry had every entry been there; the other
 * entries come after it and need not be there */
static int ensure_proxy(Core *self) {
    if (!self->own_heap || self->hn == 0) return 0;
    Deliveries *d = self->heap[0].d;
    if (d->proxied) return 0;
    PyObject *t = PyFloat_FromDouble(d->at);
    if (t == NULL) return -1;
    Py_INCREF(self->cb);
    Py_XSETREF(d->callbacks, self->cb);
    int rc = push_simpy(self, d, t, d->eid);
    Py_DECREF(t);
    if (rc == 0) d->proxied = 1;
    return rc;
}

/* the int attribute `name` of obj */
static int get_ll(PyObject *obj, PyObject *name, long long *out) {
    PyObject *v = PyObject_GetAttr(obj, name);
    if (v == NULL) return -1;
    *out = PyLong_AsLongLong(v);
    Py_DECREF(v);
    return *out == -1 && PyErr_Occurred() ? -1 : 0;
}

/* start(pkt, dst, t0, duration, links, forget): AcousticChannel._start's loop over the heard
 * receivers (dst None: a broadcast; else only dst delivers, every receiver records the signal)
 * and the push of the first delivery. Returns whether anything was queued. */
static PyObject *Core_start(Core *self, PyObject *args) {
    PyObject *pkt, *dst, *links;
    double t0, duration, forget;
    if (!PyArg_ParseTuple(args, "OOddO!d", &pkt, &dst, &t0, &duration, &LinksType, &links, &forget)) return NULL;
    if (self->cb == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "start: the core was cleared");
        return NULL;
    }
    Links *L = (Links *)links;
    long long want = -1, uid, src;
    if (dst != Py_None) {
        want = PyLong_AsLongLong(dst);
        if (want == -1 && PyErr_Occurred()) return NULL;
    }
    if (get_ll(pkt, s_uid, &uid) < 0 || get_ll(pkt, s_src, &src) < 0) return NULL;
    int track = self->collision != 0;
    Py_ssize_t first = -1;
    if (track) {
        /* the receivers' state is scattered over memory in a large network: ask for every
         * receiver's node, then its log's tail, before touching any, so the misses overlap */
        for (Py_ssize_t i = 0; i < L->n; i++)
            if (L->h[i].rid < self->n) __builtin_prefetch(&self->nodes[L->h[i].rid], 1);
        for (Py_ssize_t i = 0; i < L->n; i++)
            if (L->h[i].rid < self->n) {
                const Node *nd = &self->nodes[L->h[i].rid];
                if (nd->nsig) {
                    __builtin_prefetch(nd->sig, 1);
                    __builtin_prefetch(nd->sig + nd->nsig - 1, 1);
                }
            }
    }
    for (Py_ssize_t i = 0; i < L->n; i++) {
        Heard *h = &L->h[i];
        if (h->rid >= self->n) {
            PyErr_Format(PyExc_IndexError, "start: no node %zd on this channel", h->rid);
            return NULL;
        }
        if (h->rid == want && first < 0) first = i;
        if (track) {
            double arr = t0 + h->tof;
            double end = arr + duration;
            if (record(&self->nodes[h->rid], arr, end, h->snr, uid, forget) < 0) return NULL;
        }
    }
    Py_ssize_t k0 = 0, n = L->n;
    if (want >= 0) { /* a unicast: only the addressee delivers */
        if (first < 0) Py_RETURN_FALSE;
        k0 = first;
        n = first + 1;
    }
    if (n <= k0) Py_RETURN_FALSE;
    Deliveries *d = PyObject_GC_New(Deliveries, &DeliveriesType);
    if (d == NULL) return NULL;
    Py_INCREF(self->cb);
    d->callbacks = self->cb;
    Py_INCREF(self);
    d->core = self;
    Py_INCREF(L);
    d->links = L;
    d->hs = L->h;
    Py_INCREF(pkt);
    d->pkt = pkt;
    d->kind = PyObject_GetAttr(pkt, s_kind);
    d->bits = PyObject_GetAttr(pkt, s_bits);
    d->uid_o = PyLong_FromLongLong(uid);
    d->src_o = PyLong_FromLongLong(src);
    d->dst_o = PyLong_FromLongLong(want);
    d->uid = uid;
    d->t0 = t0;
    d->duration = duration;
    d->k = k0;
    d->cur = L->h[k0];
    d->n = n;
    d->pressure = 0;
    d->proxied = 0;
    d->at = 0.0;
    d->eid = NULL;
    PyObject_GC_Track(d);
    if (d->kind == NULL || d->bits == NULL || d->uid_o == NULL || d->src_o == NULL || d->dst_o == NULL) {
        Py_DECREF(d);
        return NULL;
    }
    if (self->pressure_kind != Py_None) {
        int eq = PyObject_RichCompareBool(d->kind, self->pressure_kind, Py_EQ);
        if (eq < 0) {
            Py_DECREF(d);
            return NULL;
        }
        d->pressure = eq;
    }
    /* the first end: t0 + (sigs[0][1] - t0) with sigs[0][1] = (t0 + T) + duration */
    double arr = t0 + d->cur.tof;
    double end = arr + duration;
    int rc = push(self, d, t0 + (end - t0));
    Py_DECREF(d);
    if (rc < 0 || ensure_proxy(self) < 0) return NULL;
    Py_RETURN_TRUE;
}

/* _scan: 0 (received), 1 half duplex, 2 collision, -1 error */
static int scan(Core *self, Node *rx, double arr, double end, double snr, long long uid) {
    if (rx->busy_until > arr) {
        Py_ssize_t n = rx->ntx;
        const Tx *tx = rx->tx;
        for (Py_ssize_t i = tx_left(tx, n, arr - 2.0 * self->max_duration); i < n && tx[i].start < end; i++)
            if (tx[i].end > arr) return 1;
    }
    if (self->collision == 0) return 0;
    int destructive = self->collision == 1;
    Py_ssize_t n = rx->nsig;
    const Sig *sig = rx->sig;
    double power = 0.0;
    int hit = 0;
    for (Py_ssize_t i = sig_left(sig, n, arr - self->max_duration); i < n; i++) {
        if (sig[i].arr >= end) break;
        if (sig[i].end > arr && sig[i].uid != uid) {
            hit = 1;
            if (destructive) break;
            double x = sig[i].snr / 10.0;
            double p = pow(10.0, x);
            if (isinf(p) && isfinite(x)) { /* float.__pow__ raises on overflow */
                PyErr_SetString(PyExc_OverflowError, "(34, 'Numerical result out of range')");
                return -1;
            }
            power += p;
        }
    }
    if (!hit) return 0;
    if (destructive) return 2;
    if (!(power > 0.0) && !isnan(power)) { /* math.log10 of 0 */
        PyErr_SetString(PyExc_ValueError, "math domain error");
        return -1;
    }
    return !(snr - 10.0 * log10(power) >= self->capture_db) ? 2 : 0;
}

/* one delivery of d (its k-th): AcousticChannel._next_delivery's body up to the next push */
static int deliver_one(Core *self, Deliveries *d) {
    const Heard *h = &d->cur;
    /* what this delivery reads after the node's deliver (the next record, for its push), and
     * the receiver's state, asked for now: in a large network each is a miss, and asked for
     * together they overlap */
    if (d->k + 1 < d->n) __builtin_prefetch(d->hs + d->k + 1);
    __builtin_prefetch(d->src_o, 1);
    __builtin_prefetch(d->uid_o, 1);
    Node *rx = &self->nodes[h->rid];
    /* every line of the signal log at once, so the bisection's misses overlap (a log holds
     * about 15 signals, 8 lines, at 16 neighbours); a log over 1 KiB (dense traffic) is left to
     * the bisection, which reads only about log2(n) lines of it */
    if (rx->nsig && (size_t)rx->nsig * sizeof(Sig) <= 1024) {
        const char *p = (const char *)rx->sig, *e = (const char *)(rx->sig + rx->nsig);
        for (; p < e; p += 64) __builtin_prefetch(p);
    }
    /* the port's first line (its reference count and, for a _NodeCore, every slot its deliver
     * reads) and the next, for a port not aligned to a line */
    const char *port = (const char *)untag(rx->deliver);
    __builtin_prefetch(port, 1);
    __builtin_prefetch(port + 63, 1);
    double arr = d->t0 + h->tof;
    double end = arr + d->duration;
    int v = scan(self, rx, arr, end, h->snr, d->uid);
    if (v < 0) return -1;
    PyObject *row = PyTuple_New(13);
    if (row == NULL) return -1;
    /* the row's own objects (the tuple owns them from here, so one DECREF of it frees them all) */
    PyObject *arr_obj = PyFloat_FromDouble(arr), *rid = PyLong_FromSsize_t(h->rid);
    /* the delay and SNR as new objects: the link's own would be a cold line each */
    PyObject *tof = PyFloat_FromDouble(h->tof), *snr = PyFloat_FromDouble(h->snr);
    PyTuple_SET_ITEM(row, 0, arr_obj);
    PyTuple_SET_ITEM(row, 3, rid);
    PyTuple_SET_ITEM(row, 9, tof);
    PyTuple_SET_ITEM(row, 10, snr);
    if (!arr_obj || !rid || !tof || !snr) {
        Py_DECREF(row);
        return -1;
    }
    PyObject *shared[3] = {d->src_o, d->dst_o, d->uid_o};
    static const int at[3] = {4, 5, 6};
    for (int i = 0; i < 3; i++) {
        Py_INCREF(shared[i]);
        PyTuple_SET_ITEM(row, at[i], shared[i]);
    }
    Py_INCREF(d->kind);
    PyTuple_SET_ITEM(row, 7, d->kind);
    Py_INCREF(d->bits);
    PyTuple_SET_ITEM(row, 8, d->bits);
    Py_INCREF(h->path);
    PyTuple_SET_ITEM(row, 11, h->path);
    PyObject *event = v == 0 ? s_rx : s_drop;
    PyObject *reason = v == 0 ? Py_None : v == 1 ? s_half_duplex : s_collision;
    Py_INCREF(event);
    PyTuple_SET_ITEM(row, 1, event);
    Py_INCREF(reason);
    PyTuple_SET_ITEM(row, 2, reason);
    PyObject *rx_local;
    if (v == 0) {
        if (rx->a > 0.0 && !self->jitter) {
            rx_local = PyFloat_FromDouble(rx->a * arr + rx->b);
        } else {
            PyObject *argv[2] = {rid, arr_obj};
            rx_local = PyObject_Vectorcall(self->stamp, argv, 2, NULL);
        }
        if (rx_local == NULL) {
            Py_DECREF(row);
            return -1;
        }
        PyTuple_SET_ITEM(row, 12, rx_local);
        PyObject *p;
        if (d->pressure) {
            PyObject *ts = PyFloat_FromDouble(arr - h->tof);
            if (ts == NULL) {
                Py_DECREF(row);
                return -1;
            }
            PyObject *argv[4] = {d->pkt, rid, ts, arr_obj};
            p = PyObject_Vectorcall(self->pressure, argv, 4, NULL);
            Py_DECREF(ts);
            if (p == NULL) {
                Py_DECREF(row);
                return -1;
            }
        } else {
            Py_INCREF(self->nan);
            p = self->nan;
        }
        PyObject *r;
        if ((uintptr_t)rx->deliver & PORT) {
            PyObject *argv[5] = {untag(rx->deliver), d->pkt, rx_local, snr, p};
            r = PyObject_Vectorcall(self->deliver_fn, argv, 5, NULL);
        } else {
            PyObject *argv[4] = {d->pkt, rx_local, snr, p};
            r = PyObject_Vectorcall(rx->deliver, argv, 4, NULL);
        }
        Py_DECREF(p);
        if (r == NULL) {
            Py_DECREF(row);
            return -1;
        }
        Py_DECREF(r);
    } else {
        Py_INCREF(self->nan);
        PyTuple_SET_ITEM(row, 12, self->nan);
    }
    int rc = PyList_Append(self->rows, row);
    Py_DECREF(row);
    return rc;
}

/* whether the own heap's head precedes SimPy's entry `head` (time, priority, eid, event):
 * the order of the tuples' comparison */
static int head_first(Core *self, PyObject *head, int *err) {
    HEnt *h = &self->heap[0];
    double t = PyFloat_AsDouble(PyTuple_GET_ITEM(head, 0));
    long prio = PyLong_AsLong(PyTuple_GET_ITEM(head, 1));
    long long eid = PyLong_AsLongLong(PyTuple_GET_ITEM(head, 2));
    if (PyErr_Occurred()) {
        *err = 1;
        return 0;
    }
    if (h->t != t) return h->t < t;
    if (self->prio != prio) return self->prio < prio;
    return h->eid < eid;
}

/* run(ev): the callback of every channel entry (AcousticChannel._next_delivery). After each
 * delivery, while the next entry in SimPy's order is another of this channel's, take it here
 * as Environment.step would have next: from SimPy's queue (the same pop of the same heap), or
 * with the own heap, the own head while it precedes SimPy's head */
static PyObject *Core_run(Core *self, PyObject *ev) {
    if (Py_TYPE(ev) != &DeliveriesType || ((Deliveries *)ev)->core != self) {
        PyErr_SetString(PyExc_TypeError, "run: not a delivery entry of this channel");
        return NULL;
    }
    if (self->cb == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "run: the core was cleared");
        return NULL;
    }
    Deliveries *d = (Deliveries *)ev;
    if (self->own_heap) {
        if (self->hn == 0 || self->heap[0].d != d) {
            PyErr_SetString(PyExc_RuntimeError, "run: the entry is not the head of the channel's heap");
            return NULL;
        }
        d->proxied = 0;
        heap_pop(self); /* its reference is ours now */
    } else {
        Py_INCREF(d);
    }
    for (;;) {
        if (deliver_one(self, d) < 0) goto fail;
        Py_ssize_t k = d->k + 1;
        if (k < d->n) { /* queued after the delivery's own events (their sequence numbers) */
            d->k = k;
            if (!self->own_heap) {
                Py_INCREF(self->cb);
                Py_XSETREF(d->callbacks, self->cb); /* Environment.step set it to None */
            }
            d->cur = d->hs[k];
            double end = (d->t0 + d->cur.tof) + d->duration;
            if (push(self, d, d->t0 + (end - d->t0)) < 0) goto fail;
        }
        if (!self->drain) break;
        if (self->cq) {
            /* the compiled queue's head: next iff it is an entry of this channel */
            PyObject *nxt = events_api->head(self->queue);
            if (nxt == NULL || Py_TYPE(nxt) != &DeliveriesType || ((Deliveries *)nxt)->callbacks != self->cb) break;
            Deliveries *popped = (Deliveries *)events_api->pop_now(self->queue); /* env._now: its time */
            Py_DECREF(d);
            d = popped;
            if (d == NULL) return NULL;
            continue;
        }
        Py_ssize_t qn = PyList_GET_SIZE(self->queue);
        PyObject *head = qn ? PyList_GET_ITEM(self->queue, 0) : NULL;
        if (head != NULL && (!PyTuple_Check(head) || PyTuple_GET_SIZE(head) != 4)) break;
        PyObject *nxt = head ? PyTuple_GET_ITEM(head, 3) : NULL;
        Deliveries *next_d;
        if (self->own_heap) {
            if (self->hn == 0) break;
            Deliveries *h = self->heap[0].d;
            if (h->proxied) {
                /* its proxy is on SimPy's queue with its key: next iff it is SimPy's head */
                if (nxt != (PyObject *)h) break;
            } else {
                /* not on SimPy's queue: next iff it precedes SimPy's head (which then cannot
                 * be an entry of this channel: they all come after the own head) */
                int err = 0;
                if (head != NULL && !head_first(self, head, &err)) {
                    if (err) goto fail;
                    break;
                }
                PyObject *t = PyFloat_FromDouble(self->heap[0].t);
                if (t == NULL) goto fail;
                int rc = PyObject_SetAttr(self->env, s_now, t);
                Py_DECREF(t);
                next_d = heap_pop(self);
                Py_DECREF(d);
                d = next_d;
                if (rc < 0) goto fail;
                continue;
            }
        } else if (nxt == NULL || Py_TYPE(nxt) != &DeliveriesType || ((Deliveries *)nxt)->callbacks != self->cb) {
            break; /* an event of SimPy's, of a node or of another channel: step() takes it */
        }
        /* SimPy's head is this channel's entry (with the own heap: its head's proxy) */
        PyObject *argv[1] = {self->queue};
        PyObject *popped = PyObject_Vectorcall(heappop_fn, argv, 1, NULL);
        if (popped == NULL) goto fail;
        int rc = PyObject_SetAttr(self->env, s_now, PyTuple_GET_ITEM(popped, 0));
        next_d = (Deliveries *)PyTuple_GET_ITEM(popped, 3);
        if (self->own_heap) {
            next_d->proxied = 0;
            heap_pop(self);
        } else {
            Py_INCREF(next_d);
        }
        Py_DECREF(popped);
        Py_DECREF(d);
        d = next_d;
        if (rc < 0) goto fail;
    }
    Py_DECREF(d);
    if (ensure_proxy(self) < 0) return NULL;
    Py_RETURN_NONE;
fail:
    Py_DECREF(d);
    return NULL;
}

/* signals(node): how many signals the log at node keeps (AcousticChannel.signals_at) */
static PyObject *Core_signals(Core *self, PyObject *arg) {
    Py_ssize_t i = PyLong_AsSsize_t(arg);
    if (i == -1 && PyErr_Occurred()) return NULL;
    Node *nd = node_at(self, i);
    return nd == NULL ? NULL : PyLong_FromSsize_t(nd->nsig);
}

static PyMethodDef Core_methods[] = {
    {"attach", (PyCFunction)Core_attach, METH_VARARGS, "attach(deliver, exact, skew, offset): the next node"},
    {"transmit", (PyCFunction)Core_transmit, METH_VARARGS, "transmit(node, start, end, now): an own transmission"},
    {"pack", (PyCFunction)Core_pack, METH_O, "pack(heard): the heard receivers of a transmission, packed"},
    {"start", (PyCFunction)Core_start, METH_VARARGS, "start(pkt, dst, t0, duration, links, forget)"},
    {"run", (PyCFunction)Core_run, METH_O, "run(entry): decide deliveries (the entries' callback)"},
    {"signals", (PyCFunction)Core_signals, METH_O, "signals(node): signals kept at node"},
    {NULL, NULL, 0, NULL},
};

static PyMemberDef Core_members[] = {
    {"max_duration", T_DOUBLE, offsetof(Core, max_duration), 0, "the channel's longest packet so far (s)"},
    {"drain", T_INT, offsetof(Core, drain), 0, "decide consecutive head entries in one loop"},
    {NULL, 0, 0, 0, NULL},
};

static PyTypeObject CoreType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "aquasim_py.channel._delivery.Core",
    .tp_basicsize = sizeof(Core),
    .tp_dealloc = (destructor)Core_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC,
    .tp_doc = "every node's channel-side state and the delivery loop of one AcousticChannel",
    .tp_traverse = (traverseproc)Core_traverse,
    .tp_clear = (inquiry)Core_clear,
    .tp_methods = Core_methods,
    .tp_members = Core_members,
    .tp_init = (initproc)Core_init,
    .tp_new = PyType_GenericNew,
};

/* ------------------------------------------------------------------------------------------ */
/* Deliveries: one transmission's deliveries as one entry at a time on SimPy's queue */

static int Deliveries_traverse(Deliveries *self, visitproc visit, void *arg) {
    Py_VISIT(self->callbacks);
    Py_VISIT(self->core);
    Py_VISIT(self->pkt);
    return 0;
}

static int Deliveries_clear(Deliveries *self) {
    Py_CLEAR(self->callbacks);
    Py_CLEAR(self->core);
    Py_CLEAR(self->pkt);
    return 0;
}

static void Deliveries_dealloc(Deliveries *self) {
    PyObject_GC_UnTrack(self);
    Deliveries_clear(self);
    Py_XDECREF(self->links);
    Py_XDECREF(self->kind);
    Py_XDECREF(self->bits);
    Py_XDECREF(self->uid_o);
    Py_XDECREF(self->src_o);
    Py_XDECREF(self->dst_o);
    Py_XDECREF(self->eid);
    PyObject_GC_Del(self);
}

static PyObject *Deliveries_ok(PyObject *self, void *closure) { Py_RETURN_TRUE; }

static PyObject *Deliveries_get_callbacks(Deliveries *self, void *closure) {
    PyObject *c = self->callbacks ? self->callbacks : Py_None;
    Py_INCREF(c);
    return c;
}

static int Deliveries_set_callbacks(Deliveries *self, PyObject *value, void *closure) {
    if (value == NULL) {
        PyErr_SetString(PyExc_AttributeError, "callbacks cannot be deleted");
        return -1;
    }
    Py_INCREF(value);
    Py_XSETREF(self->callbacks, value);
    return 0;
}

static PyGetSetDef Deliveries_getset[] = {
    {"_ok", (getter)Deliveries_ok, NULL, "always True (what Environment.step checks)", NULL},
    {"callbacks", (getter)Deliveries_get_callbacks, (setter)Deliveries_set_callbacks, NULL, NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyTypeObject DeliveriesType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "aquasim_py.channel._delivery.Deliveries",
    .tp_basicsize = sizeof(Deliveries),
    .tp_dealloc = (destructor)Deliveries_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC,
    .tp_doc = "one transmission's deliveries, one entry at a time on SimPy's queue",
    .tp_traverse = (traverseproc)Deliveries_traverse,
    .tp_clear = (inquiry)Deliveries_clear,
    .tp_getset = Deliveries_getset,
};

/* ------------------------------------------------------------------------------------------ */

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_delivery",
    "The acoustic channel's per-reception work in C (see aquasim_py/channel/acoustic.py).", -1, NULL,
};

PyMODINIT_FUNC PyInit__delivery(void) {
    if (PyType_Ready(&LinksType) < 0 || PyType_Ready(&CoreType) < 0 || PyType_Ready(&DeliveriesType) < 0) return NULL;
#define INTERN(v, s) if ((v = PyUnicode_InternFromString(s)) == NULL) return NULL
    INTERN(s_rx, "rx");
    INTERN(s_drop, "drop");
    INTERN(s_half_duplex, "half_duplex");
    INTERN(s_collision, "collision");
    INTERN(s_now, "_now");
    INTERN(s_uid, "uid");
    INTERN(s_src, "src");
    INTERN(s_kind, "kind");
    INTERN(s_bits, "bits");
#undef INTERN
    PyObject *heapq = PyImport_ImportModule("heapq");
    if (heapq == NULL) return NULL;
    heappush_fn = PyObject_GetAttrString(heapq, "heappush");
    heappop_fn = PyObject_GetAttrString(heapq, "heappop");
    Py_DECREF(heapq);
    if (heappush_fn == NULL || heappop_fn == NULL) return NULL;
    /* PyCapsule_Import reads attributes from the package down, so the submodule first */
    PyObject *events_mod = PyImport_ImportModule("aquasim_py._events");
    events_api = events_mod ? PyCapsule_Import(AQUASIM_EVENTS_CAPSULE, 0) : NULL;
    Py_XDECREF(events_mod);
    if (events_api == NULL) PyErr_Clear(); /* not built: the channel uses SimPy's list heap */
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    if (PyModule_AddIntConstant(m, "EVENTS", events_api != NULL) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    if (PyModule_AddObjectRef(m, "Core", (PyObject *)&CoreType) < 0 ||
        PyModule_AddObjectRef(m, "Links", (PyObject *)&LinksType) < 0 ||
        PyModule_AddObjectRef(m, "Deliveries", (PyObject *)&DeliveriesType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
