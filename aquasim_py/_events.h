/* The C-level interface of aquasim_py._events (its _C_API capsule), for the channel's
 * compiled delivery (aquasim_py/channel/_delivery.c), which queues its entries directly. */
#ifndef AQUASIM_EVENTS_H
#define AQUASIM_EVENTS_H
#include <Python.h>

#define AQUASIM_EVENTS_CAPSULE "aquasim_py._events._C_API"

typedef struct {
    PyTypeObject *QueueType;
    /* push ev at time t (an exact float), priority prio, the queue's next sequence number */
    int (*push)(PyObject *queue, double t, long prio, PyObject *ev);
    /* the first event (borrowed), or NULL when empty (no error set) */
    PyObject *(*head)(PyObject *queue);
    /* pop the first event (a new reference) and set the environment's _now to its time */
    PyObject *(*pop_now)(PyObject *queue);
} AquasimEventsAPI;

#endif
