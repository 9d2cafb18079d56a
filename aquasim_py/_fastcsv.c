/* CSV text of trace chunks (see aquasim_py/trace.py); placeholder until implemented. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_fastcsv", "CSV text of trace chunks (see aquasim_py/trace.py)", 0, NULL};

PyMODINIT_FUNC PyInit__fastcsv(void) { return PyModule_Create(&module); }
