/* cobot_hmi.native._cyclic_pump: the cyclic pump (cyclic_pump.c) as a CPython extension type.
 *
 * Built by setuptools when the package is built (backend/setup.py), so a wheel carries it
 * compiled and nothing is compiled at run time. Why an extension rather than ctypes or CFFI:
 * it needs no run-time dependency, a received datagram becomes a bytes object in one copy,
 * each call costs a method call rather than ctypes' per-argument conversions, and the object's
 * deallocation stops the thread (a finalizer that cannot be forgotten). The interface matches
 * cobot_hmi.native.pure.Pump, the pure-Python path (_cyclic_pump.pyi types it).
 *
 * Every method runs with the GIL held, so two Python threads never use `scratch` at once; the
 * pump's own lock orders them against its thread. close() takes the pointer out of the object
 * before stopping the thread, so no later call can reach a freed pump.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <string.h>

#include "cyclic_pump.h"

#define TAKE_MAX 64 /* datagrams moved out of the ring per take() */

typedef struct {
    PyObject_HEAD
    pump *p;
    int ring_bytes;
    uint8_t *scratch; /* TAKE_MAX * ring_bytes: what take() copies out under the pump's lock */
} PumpObject;

static pump *get(PumpObject *self) {
    if (!self->p) PyErr_SetString(PyExc_ValueError, "the cyclic pump is closed");
    return self->p;
}

static int Pump_init(PumpObject *self, PyObject *args, PyObject *kwds) {
    static char *names[] = {"fd", "queue_cap", "queue_bytes", "ring_cap", "ring_bytes", NULL};
    int fd, queue_cap, queue_bytes, ring_cap, ring_bytes;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "iiiii", names, &fd, &queue_cap, &queue_bytes,
                                     &ring_cap, &ring_bytes))
        return -1;
    if (self->p) {
        PyErr_SetString(PyExc_RuntimeError, "the cyclic pump is already running");
        return -1;
    }
    if (fd < 0 || queue_cap <= 0 || queue_bytes <= 0 || ring_cap <= 0 || ring_bytes <= 0) {
        PyErr_SetString(PyExc_ValueError, "a pump needs a socket and positive sizes");
        return -1;
    }
    PyMem_Free(self->scratch); /* a second __init__ after a failed one */
    self->scratch = PyMem_Malloc((size_t)TAKE_MAX * (size_t)ring_bytes);
    if (!self->scratch) {
        PyErr_NoMemory();
        return -1;
    }
    self->ring_bytes = ring_bytes;
    pump *p = pump_new(fd, queue_cap, queue_bytes, ring_cap, ring_bytes);
    if (!p) {
        PyErr_SetString(PyExc_OSError, "cannot create the cyclic pump (memory or eventfd)");
        return -1;
    }
    if (pump_start(p) != 0) {
        pump_free(p);
        PyErr_SetString(PyExc_OSError, "cannot start the cyclic pump thread");
        return -1;
    }
    self->p = p;
    return 0;
}

static PyObject *Pump_close(PumpObject *self, PyObject *Py_UNUSED(ignored)) {
    pump *p = self->p;
    self->p = NULL;
    if (p) {
        Py_BEGIN_ALLOW_THREADS
        pump_free(p); /* joins the thread, which never takes the GIL */
        Py_END_ALLOW_THREADS
    }
    Py_RETURN_NONE;
}

static void Pump_dealloc(PumpObject *self) {
    pump_free(self->p); /* the finalizer: a pump dropped unclosed stops its thread */
    self->p = NULL;
    PyMem_Free(self->scratch);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *Pump_enter(PumpObject *self, PyObject *Py_UNUSED(ignored)) {
    return Py_NewRef(self);
}

static PyObject *Pump_exit(PumpObject *self, PyObject *Py_UNUSED(args)) {
    return Pump_close(self, NULL);
}

static PyObject *Pump_notify_fd(PumpObject *self, PyObject *Py_UNUSED(ignored)) {
    pump *p = get(self);
    return p ? PyLong_FromLong(pump_notify_fd(p)) : NULL;
}

static PyObject *Pump_configure(PumpObject *self, PyObject *args) {
    int read_on_readable;
    long long notify_interval_ns, silence_ns;
    if (!PyArg_ParseTuple(args, "pLL", &read_on_readable, &notify_interval_ns, &silence_ns))
        return NULL;
    pump *p = get(self);
    if (!p) return NULL;
    pump_configure(p, read_on_readable, notify_interval_ns, silence_ns);
    Py_RETURN_NONE;
}

static PyObject *Pump_queue(PumpObject *self, PyObject *args) {
    long long due_ns, tag;
    unsigned int ip;
    unsigned short port;
    Py_buffer data;
    if (!PyArg_ParseTuple(args, "LIHy*L", &due_ns, &ip, &port, &data, &tag)) return NULL;
    pump *p = get(self);
    int result = p && data.len <= INT32_MAX
                     ? pump_queue(p, due_ns, ip, port, data.buf, (int)data.len, tag)
                     : -2;
    PyBuffer_Release(&data);
    return p ? PyLong_FromLong(result) : NULL;
}

static PyObject *Pump_cancel(PumpObject *self, PyObject *args) {
    long long tag, from_ns;
    if (!PyArg_ParseTuple(args, "LL", &tag, &from_ns)) return NULL;
    pump *p = get(self);
    if (!p) return NULL;
    int64_t first_due_ns = 0;
    int count = pump_cancel(p, tag, from_ns, &first_due_ns);
    return Py_BuildValue("(iL)", count, (long long)first_due_ns);
}

static PyObject *Pump_queued(PumpObject *self, PyObject *args) {
    long long tag;
    if (!PyArg_ParseTuple(args, "L", &tag)) return NULL;
    pump *p = get(self);
    return p ? PyLong_FromLong(pump_queued(p, tag)) : NULL;
}

static PyObject *Pump_take(PumpObject *self, PyObject *args) {
    int drain_first, max;
    if (!PyArg_ParseTuple(args, "pi", &drain_first, &max)) return NULL;
    pump *p = get(self);
    if (!p) return NULL;
    if (max > TAKE_MAX) max = TAKE_MAX;
    if (max < 0) max = 0;
    int32_t lens[TAKE_MAX];
    int64_t stamps[TAKE_MAX];
    uint32_t ips[TAKE_MAX];
    uint16_t ports[TAKE_MAX];
    int count = pump_take(p, drain_first, self->scratch, TAKE_MAX * self->ring_bytes, lens, stamps,
                          ips, ports, max);
    PyObject *taken = PyList_New(count);
    if (!taken) return NULL;
    size_t offset = 0;
    for (int i = 0; i < count; i++) {
        PyObject *item = Py_BuildValue("(y#IHL)", (const char *)self->scratch + offset,
                                       (Py_ssize_t)lens[i], (unsigned int)ips[i],
                                       (unsigned short)ports[i], (long long)stamps[i]);
        if (!item) {
            Py_DECREF(taken);
            return NULL; /* out of memory: what was taken is lost, as a full ring would */
        }
        PyList_SET_ITEM(taken, i, item);
        offset += (size_t)lens[i];
    }
    return taken;
}

static PyObject *Pump_counters(PumpObject *self, PyObject *Py_UNUSED(ignored)) {
    pump *p = get(self);
    if (!p) return NULL;
    int64_t values[C_COUNT];
    pump_counters(p, values);
    PyObject *tuple = PyTuple_New(C_COUNT);
    if (!tuple) return NULL;
    for (int i = 0; i < C_COUNT; i++) {
        PyObject *value = PyLong_FromLongLong(values[i]);
        if (!value) {
            Py_DECREF(tuple);
            return NULL;
        }
        PyTuple_SET_ITEM(tuple, i, value);
    }
    return tuple;
}

static PyObject *Pump_periodic_start(PumpObject *self, PyObject *args) {
    long long tag, first_due_ns, period_ns;
    unsigned int ip, first32;
    unsigned short port, first16;
    int off32, off16;
    Py_buffer data;
    if (!PyArg_ParseTuple(args, "LLLIHy*iIiH", &tag, &first_due_ns, &period_ns, &ip, &port, &data,
                          &off32, &first32, &off16, &first16))
        return NULL;
    pump *p = get(self);
    int result = p && data.len <= INT32_MAX
                     ? pump_periodic_start(p, tag, first_due_ns, period_ns, ip, port, data.buf,
                                           (int)data.len, off32, first32, off16, first16)
                     : -2;
    PyBuffer_Release(&data);
    return p ? PyLong_FromLong(result) : NULL;
}

static PyObject *Pump_periodic_data(PumpObject *self, PyObject *args) {
    long long tag;
    Py_buffer data;
    if (!PyArg_ParseTuple(args, "Ly*", &tag, &data)) return NULL;
    pump *p = get(self);
    int result = p && data.len <= INT32_MAX ? pump_periodic_data(p, tag, data.buf, (int)data.len)
                                            : -2;
    PyBuffer_Release(&data);
    return p ? PyLong_FromLong(result) : NULL;
}

static PyObject *Pump_periodic_next(PumpObject *self, PyObject *args) {
    long long tag;
    int stop;
    if (!PyArg_ParseTuple(args, "Lp", &tag, &stop)) return NULL;
    pump *p = get(self);
    if (!p) return NULL;
    uint32_t next32;
    uint16_t next16;
    int64_t next_due_ns;
    if (pump_periodic_next(p, tag, stop, &next32, &next16, &next_due_ns) != 0) Py_RETURN_NONE;
    return Py_BuildValue("(IHL)", (unsigned int)next32, (unsigned short)next16,
                         (long long)next_due_ns);
}

static PyMethodDef Pump_methods[] = {
    {"close", (PyCFunction)Pump_close, METH_NOARGS, "Stop and join the thread, free the pump."},
    {"__enter__", (PyCFunction)Pump_enter, METH_NOARGS, NULL},
    {"__exit__", (PyCFunction)Pump_exit, METH_VARARGS, NULL},
    {"notify_fd", (PyCFunction)Pump_notify_fd, METH_NOARGS, "The eventfd the owner watches."},
    {"configure", (PyCFunction)Pump_configure, METH_VARARGS, NULL},
    {"queue", (PyCFunction)Pump_queue, METH_VARARGS, NULL},
    {"cancel", (PyCFunction)Pump_cancel, METH_VARARGS, NULL},
    {"queued", (PyCFunction)Pump_queued, METH_VARARGS, NULL},
    {"take", (PyCFunction)Pump_take, METH_VARARGS, NULL},
    {"counters", (PyCFunction)Pump_counters, METH_NOARGS, NULL},
    {"periodic_start", (PyCFunction)Pump_periodic_start, METH_VARARGS, NULL},
    {"periodic_data", (PyCFunction)Pump_periodic_data, METH_VARARGS, NULL},
    {"periodic_next", (PyCFunction)Pump_periodic_next, METH_VARARGS, NULL},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject PumpType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "cobot_hmi.native._cyclic_pump.Pump",
    .tp_doc = "The cyclic pump of one UDP socket: a C thread (see cyclic_pump.c).",
    .tp_basicsize = sizeof(PumpObject),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)Pump_init,
    .tp_dealloc = (destructor)Pump_dealloc,
    .tp_methods = Pump_methods,
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT,
    .m_name = "cobot_hmi.native._cyclic_pump",
    .m_doc = "The cyclic pump (cyclic_pump.c) as an extension type.",
    .m_size = -1,
};

PyMODINIT_FUNC PyInit__cyclic_pump(void) {
    if (PyType_Ready(&PumpType) < 0) return NULL;
    PyObject *m = PyModule_Create(&module);
    if (!m) return NULL;
    if (PyModule_AddObjectRef(m, "Pump", (PyObject *)&PumpType) < 0 ||
        PyModule_AddIntConstant(m, "TAKE_MAX", TAKE_MAX) < 0 ||
        PyModule_AddIntConstant(m, "PERIODIC_MAX", PUMP_PERIODIC_MAX) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
