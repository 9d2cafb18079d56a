/* the channel's delivery decisions (see aquasim_py/channel/acoustic.py); placeholder until implemented. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_delivery", "the channel's delivery decisions (see aquasim_py/channel/acoustic.py)", 0, NULL};

PyMODINIT_FUNC PyInit__delivery(void) { return PyModule_Create(&module); }
