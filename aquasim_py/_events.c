/* The kernel's event queue in C (aquasim_py/events.py: Environment, the SimPy Environment
 * that uses it; without this extension the kernel runs on simpy.Environment itself).
 *
 * SimPy keeps its scheduled events in a list heap of tuples (time, priority, sequence number,
 * event): every comparison of a sift follows a pointer to a tuple and another to its time, so
 * with thousands of pending events (one sleeping process per node) each push and pop touches
 * as many scattered objects as the heap has levels. Here the key is stored in the heap entry
 * itself (time as a double, priority, sequence number): the heap is one array, a pop touches
 * only it and the popped event. The order is SimPy's: (time, priority, sequence number)
 * compared in that order, with the sequence numbers drawn from this queue's own counter, the
 * one Environment._eid iterates (it is this object).
 *
 * Queue.step is Environment.step (SimPy 4.1's, statement for statement): pop the first event,
 * set env._now to its time, run its callbacks, crash on a failed event nobody defused. With
 * requeue (SimPy >= 4.1.2) a StopSimulation raised by a callback puts the event's remaining
 * callbacks back on it and reschedules it at priority -1, as that release's step does; before
 * it, the exception just propagates.
 *
 * Times: an exact float is kept as a double and made again at the pop (the same value); any
 * other time (an int, a float subclass) is kept as the object itself, so env.now has the type
 * SimPy would have given it. A NaN time is refused: it has no place in SimPy's order either.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#include "_events.h"

typedef struct {
    double t;          /* the key: time, priority, sequence number */
    long long eid;
    PyObject *ev;      /* owned */
    PyObject *t_obj;   /* owned, or NULL: t is an exact float */
    long prio;
} Ent;

typedef struct {
    PyObject_HEAD
    Ent *h;
    Py_ssize_t n, cap;
    long long next_eid;
    PyObject *env;     /* the Environment whose _now step sets (owned; a cycle the GC breaks) */
    int requeue;       /* on StopSimulation, reschedule the remaining callbacks (SimPy >= 4.1.2) */
} Queue;

static PyTypeObject QueueType;
static PyObject *s_now, *s_callbacks, *s_ok, *s_value, *s_defused, *s_args, *s_schedule;
static PyObject *EmptySchedule, *StopSimulation;

static inline int less(const Ent *a, const Ent *b) {
    if (a->t != b->t) return a->t < b->t;
    if (a->prio != b->prio) return a->prio < b->prio;
    return a->eid < b->eid;
}

/* the entry's reference moves in */
static int q_insert(Queue *q, Ent e) {
    if (q->n == q->cap) {
        Py_ssize_t cap = q->cap ? 2 * q->cap : 1024;
        Ent *h = PyMem_Realloc(q->h, (size_t)cap * sizeof(Ent));
        if (h == NULL) {
            PyErr_NoMemory();
            return -1;
        }
        q->h = h;
        q->cap = cap;
    }
    Ent *h = q->h;
    Py_ssize_t pos = q->n++;
    while (pos > 0) {
        Py_ssize_t parent = (pos - 1) >> 1;
        if (!less(&e, &h[parent])) break;
        h[pos] = h[parent];
        pos = parent;
    }
    h[pos] = e;
    return 0;
}

/* the first entry; its references move out (n > 0) */
static Ent q_remove(Queue *q) {
    Ent *h = q->h;
    Ent top = h[0];
    Ent last = h[--q->n];
    Py_ssize_t n = q->n, pos = 0;
    if (n > 0) {
        for (;;) {
            Py_ssize_t c = 2 * pos + 1;
            if (c >= n) break;
            if (c + 1 < n && less(&h[c + 1], &h[c])) c++;
            if (!less(&h[c], &last)) break;
            h[pos] = h[c];
            pos = c;
        }
        h[pos] = last;
    }
    return top;
}

/* push(t, prio, ev): t a number (the event's time), the next sequence number */
static int q_push_obj(Queue *q, PyObject *t, long prio, PyObject *ev) {
    double tv;
    PyObject *keep = NULL;
    if (PyFloat_CheckExact(t)) {
        tv = PyFloat_AS_DOUBLE(t);
    } else {
        tv = PyFloat_AsDouble(t);
        if (tv == -1.0 && PyErr_Occurred()) return -1;
        keep = t;
    }
    if (isnan(tv)) {
        PyErr_SetString(PyExc_ValueError, "an event cannot be scheduled at time NaN");
        return -1;
    }
    Py_XINCREF(keep);
    Py_INCREF(ev);
    if (q_insert(q, (Ent){tv, q->next_eid, ev, keep, prio}) < 0) {
        Py_XDECREF(keep);
        Py_DECREF(ev);
        return -1;
    }
    q->next_eid++;
    return 0;
}

static int c_push(PyObject *q, double t, long prio, PyObject *ev) {
    if (isnan(t)) {
        PyErr_SetString(PyExc_ValueError, "an event cannot be scheduled at time NaN");
        return -1;
    }
    Queue *Q = (Queue *)q;
    Py_INCREF(ev);
    if (q_insert(Q, (Ent){t, Q->next_eid, ev, NULL, prio}) < 0) {
        Py_DECREF(ev);
        return -1;
    }
    Q->next_eid++;
    return 0;
}

static PyObject *c_head(PyObject *q) {
    Queue *Q = (Queue *)q;
    return Q->n ? Q->h[0].ev : NULL;
}

/* pop the first entry, set env._now to its time; the event (a new reference) */
static PyObject *c_pop_now(PyObject *q) {
    Queue *Q = (Queue *)q;
    if (Q->n == 0) {
        PyErr_SetNone(EmptySchedule);
        return NULL;
    }
    Ent e = q_remove(Q);
    /* the next event is needed at the next step, after this one's callbacks: asked for now,
     * its object is in cache by then (in a large network it is a miss) */
    if (Q->n) {
        const char *nx = (const char *)Q->h[0].ev;
        __builtin_prefetch(nx, 1);
        __builtin_prefetch(nx + 64, 1);
        __builtin_prefetch(nx + 128, 1);
    }
    PyObject *t = e.t_obj ? e.t_obj : PyFloat_FromDouble(e.t);
    if (t == NULL) {
        Py_DECREF(e.ev);
        return NULL;
    }
    int rc = Q->env ? PyObject_SetAttr(Q->env, s_now, t) : 0;
    Py_DECREF(t);
    if (rc < 0) {
        Py_DECREF(e.ev);
        return NULL;
    }
    return e.ev;
}

/* ------------------------------------------------------------------------------------------ */

static int Queue_traverse(Queue *self, visitproc visit, void *arg) {
    for (Py_ssize_t i = 0; i < self->n; i++) {
        Py_VISIT(self->h[i].ev);
        Py_VISIT(self->h[i].t_obj);
    }
    Py_VISIT(self->env);
    return 0;
}

static int Queue_clear(Queue *self) {
    Py_ssize_t n = self->n;
    self->n = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        Py_CLEAR(self->h[i].ev);
        Py_CLEAR(self->h[i].t_obj);
    }
    Py_CLEAR(self->env);
    return 0;
}

static void Queue_dealloc(Queue *self) {
    PyObject_GC_UnTrack(self);
    Queue_clear(self);
    PyMem_Free(self->h);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int Queue_init(Queue *self, PyObject *args, PyObject *kwds) {
    static char *kw[] = {"env", "requeue", NULL};
    PyObject *env = Py_None;
    int requeue = 1;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "|Op", kw, &env, &requeue)) return -1;
    self->requeue = requeue;
    Py_XSETREF(self->env, env == Py_None ? NULL : Py_NewRef(env));
    return 0;
}

static PyObject *Queue_push(Queue *self, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "push(time, priority, event)");
        return NULL;
    }
    long prio = PyLong_AsLong(args[1]);
    if (prio == -1 && PyErr_Occurred()) return NULL;
    if (q_push_obj(self, args[0], prio, args[2]) < 0) return NULL;
    Py_RETURN_NONE;
}

/* schedule(event, priority, delay): Environment.schedule (env._now + delay) */
static PyObject *Queue_schedule(Queue *self, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs < 1 || nargs > 3) {
        PyErr_SetString(PyExc_TypeError, "schedule(event, priority=NORMAL, delay=0)");
        return NULL;
    }
    if (self->env == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "schedule: the queue has no environment");
        return NULL;
    }
    long prio = 1; /* simpy.events.NORMAL */
    if (nargs >= 2) {
        prio = PyLong_AsLong(args[1]);
        if (prio == -1 && PyErr_Occurred()) return NULL;
    }
    PyObject *now = PyObject_GetAttr(self->env, s_now);
    if (now == NULL) return NULL;
    PyObject *t;
    if (nargs == 3) {
        if (PyFloat_CheckExact(now) && PyFloat_CheckExact(args[2])) {
            t = PyFloat_FromDouble(PyFloat_AS_DOUBLE(now) + PyFloat_AS_DOUBLE(args[2]));
        } else {
            t = PyNumber_Add(now, args[2]);
        }
        Py_DECREF(now);
        if (t == NULL) return NULL;
    } else {
        t = now; /* now + 0: the same value (an int stays an int, as in SimPy) */
    }
    int rc = q_push_obj(self, t, prio, args[0]);
    Py_DECREF(t);
    if (rc < 0) return NULL;
    Py_RETURN_NONE;
}

static PyObject *Queue_first(Queue *self, PyObject *unused) {
    return Py_NewRef(self->n ? self->h[0].ev : Py_None);
}

static PyObject *Queue_pop(Queue *self, PyObject *unused) { return c_pop_now((PyObject *)self); }

static PyObject *Queue_peek(Queue *self, PyObject *unused) {
    if (self->n == 0) return PyFloat_FromDouble(Py_HUGE_VAL);
    Ent *e = &self->h[0];
    return e->t_obj ? Py_NewRef(e->t_obj) : PyFloat_FromDouble(e->t);
}

/* step(): Environment.step */
static PyObject *Queue_step(Queue *self, PyObject *unused) {
    PyObject *ev = c_pop_now((PyObject *)self);
    if (ev == NULL) return NULL;
    /* callbacks, event.callbacks = event.callbacks, None */
    PyObject *callbacks = PyObject_GetAttr(ev, s_callbacks);
    if (callbacks == NULL || PyObject_SetAttr(ev, s_callbacks, Py_None) < 0) goto fail;
    if (PyList_CheckExact(callbacks)) {
        for (Py_ssize_t i = 0; i < PyList_GET_SIZE(callbacks); i++) {
            PyObject *cb = Py_NewRef(PyList_GET_ITEM(callbacks, i));
            PyObject *r = PyObject_CallOneArg(cb, ev);
            Py_DECREF(cb);
            if (r == NULL) {
                if (self->requeue && PyErr_ExceptionMatches(StopSimulation)) {
                    /* the remaining callbacks go back on the event, rescheduled first at now */
                    PyObject *etype, *evalue, *etb;
                    PyErr_Fetch(&etype, &evalue, &etb);
                    PyObject *rest = PyList_GetSlice(callbacks, i + 1, PyList_GET_SIZE(callbacks));
                    int bad = rest == NULL || PyObject_SetAttr(ev, s_callbacks, rest) < 0;
                    Py_XDECREF(rest);
                    if (!bad) {
                        PyObject *minus1 = PyLong_FromLong(-1);
                        PyObject *argv[2] = {ev, minus1};
                        PyObject *sched = minus1 ? PyObject_GetAttr(self->env, s_schedule) : NULL;
                        PyObject *rr = sched ? PyObject_Vectorcall(sched, argv, 2, NULL) : NULL;
                        Py_XDECREF(sched);
                        Py_XDECREF(minus1);
                        bad = rr == NULL;
                        Py_XDECREF(rr);
                    }
                    if (bad) {
                        Py_XDECREF(etype);
                        Py_XDECREF(evalue);
                        Py_XDECREF(etb);
                        goto fail;
                    }
                    PyErr_Restore(etype, evalue, etb);
                }
                goto fail;
            }
            Py_DECREF(r);
        }
    } else {
        PyObject *it = PyObject_GetIter(callbacks);
        if (it == NULL) goto fail;
        PyObject *cb;
        while ((cb = PyIter_Next(it)) != NULL) {
            PyObject *r = PyObject_CallOneArg(cb, ev);
            Py_DECREF(cb);
            if (r == NULL) {
                Py_DECREF(it);
                goto fail;
            }
            Py_DECREF(r);
        }
        Py_DECREF(it);
        if (PyErr_Occurred()) goto fail;
    }
    Py_DECREF(callbacks);
    callbacks = NULL;
    /* a failed event nobody defused crashes the environment, with a copy of its exception */
    PyObject *ok = PyObject_GetAttr(ev, s_ok);
    if (ok == NULL) goto fail;
    int truth = PyObject_IsTrue(ok);
    Py_DECREF(ok);
    if (truth < 0) goto fail;
    if (!truth) {
        int defused = PyObject_HasAttr(ev, s_defused);
        if (!defused) {
            PyObject *value = PyObject_GetAttr(ev, s_value);
            if (value == NULL) goto fail;
            PyObject *vargs = PyObject_GetAttr(value, s_args);
            PyObject *exc = NULL;
            if (vargs != NULL) {
                PyObject *tup = PySequence_Tuple(vargs);
                if (tup != NULL) {
                    exc = PyObject_Call((PyObject *)Py_TYPE(value), tup, NULL);
                    Py_DECREF(tup);
                }
                Py_DECREF(vargs);
            }
            if (exc == NULL) {
                Py_DECREF(value);
                goto fail;
            }
            PyException_SetCause(exc, value); /* steals value */
            PyErr_SetObject((PyObject *)Py_TYPE(exc), exc);
            Py_DECREF(exc);
            goto fail;
        }
    }
    Py_DECREF(ev);
    Py_RETURN_NONE;
fail:
    Py_XDECREF(callbacks);
    Py_DECREF(ev);
    return NULL;
}

/* the sequence counter: next(queue) is the number the next push takes (Environment._eid) */
static PyObject *Queue_iternext(Queue *self) { return PyLong_FromLongLong(self->next_eid++); }

static Py_ssize_t Queue_len(Queue *self) { return self->n; }

static PyObject *Queue_entries(Queue *self, PyObject *unused) {
    /* the entries in queue order, as SimPy's tuples (for tests and inspection; a copy) */
    Queue tmp = {.n = self->n};
    PyObject *out = PyList_New(0);
    if (out == NULL) return NULL;
    Ent *h = PyMem_Malloc((self->n ? self->n : 1) * sizeof(Ent));
    if (h == NULL) {
        Py_DECREF(out);
        return PyErr_NoMemory();
    }
    memcpy(h, self->h, self->n * sizeof(Ent));
    tmp.h = h;
    while (tmp.n) {
        Ent e = q_remove(&tmp);
        PyObject *t = e.t_obj ? Py_NewRef(e.t_obj) : PyFloat_FromDouble(e.t);
        PyObject *row = t ? Py_BuildValue("(NlLO)", t, e.prio, e.eid, e.ev) : NULL;
        if (row == NULL || PyList_Append(out, row) < 0) {
            Py_XDECREF(row);
            Py_DECREF(out);
            PyMem_Free(h);
            return NULL;
        }
        Py_DECREF(row);
    }
    PyMem_Free(h);
    return out;
}

static PyMethodDef Queue_methods[] = {
    {"push", (PyCFunction)(void (*)(void))Queue_push, METH_FASTCALL, "push(time, priority, event): at that time"},
    {"schedule", (PyCFunction)(void (*)(void))Queue_schedule, METH_FASTCALL,
     "schedule(event, priority=NORMAL, delay=0): Environment.schedule"},
    {"peek", (PyCFunction)Queue_peek, METH_NOARGS, "the first event's time (inf when empty)"},
    {"first", (PyCFunction)Queue_first, METH_NOARGS, "the first event, or None"},
    {"pop", (PyCFunction)Queue_pop, METH_NOARGS, "pop the first event and set env._now to its time"},
    {"step", (PyCFunction)Queue_step, METH_NOARGS, "Environment.step"},
    {"entries", (PyCFunction)Queue_entries, METH_NOARGS, "[(time, priority, eid, event)] in queue order"},
    {NULL, NULL, 0, NULL},
};

static PySequenceMethods Queue_as_sequence = {.sq_length = (lenfunc)Queue_len};

static PyTypeObject QueueType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "aquasim_py._events.Queue",
    .tp_basicsize = sizeof(Queue),
    .tp_dealloc = (destructor)Queue_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC,
    .tp_doc = "SimPy's event queue with the keys in the heap entries (see aquasim_py/events.py)",
    .tp_traverse = (traverseproc)Queue_traverse,
    .tp_clear = (inquiry)Queue_clear,
    .tp_iter = PyObject_SelfIter,
    .tp_iternext = (iternextfunc)Queue_iternext,
    .tp_methods = Queue_methods,
    .tp_as_sequence = &Queue_as_sequence,
    .tp_init = (initproc)Queue_init,
    .tp_new = PyType_GenericNew,
};

static AquasimEventsAPI capi = {&QueueType, c_push, c_head, c_pop_now};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_events", "The kernel's event queue in C (see aquasim_py/events.py).", -1, NULL,
};

PyMODINIT_FUNC PyInit__events(void) {
    if (PyType_Ready(&QueueType) < 0) return NULL;
#define INTERN(v, s) if ((v = PyUnicode_InternFromString(s)) == NULL) return NULL
    INTERN(s_now, "_now");
    INTERN(s_callbacks, "callbacks");
    INTERN(s_ok, "_ok");
    INTERN(s_value, "_value");
    INTERN(s_defused, "_defused");
    INTERN(s_args, "args");
    INTERN(s_schedule, "schedule");
#undef INTERN
    PyObject *core = PyImport_ImportModule("simpy.core");
    if (core == NULL) return NULL;
    EmptySchedule = PyObject_GetAttrString(core, "EmptySchedule");
    StopSimulation = PyObject_GetAttrString(core, "StopSimulation");
    Py_DECREF(core);
    if (EmptySchedule == NULL || StopSimulation == NULL) return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    PyObject *cap = PyCapsule_New(&capi, AQUASIM_EVENTS_CAPSULE, NULL);
    if (cap == NULL || PyModule_AddObjectRef(m, "Queue", (PyObject *)&QueueType) < 0 ||
        PyModule_AddObject(m, "_C_API", cap) < 0) {
        Py_XDECREF(cap);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
