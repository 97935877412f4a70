"""
A timer that ends the process with a chosen exit status and needs no GIL.

A DDS teardown that stalls inside C code holds the GIL (rclpy releases it
only while waiting), so no Python thread can run to end the process, and
faulthandler, which can, always exits with status 1.  A POSIX timer whose
expiry starts a thread of the C library that calls ``_exit(status)`` needs
neither the GIL nor the interpreter: the process then ends with the status
its run earned, whatever the main thread is stuck in.
"""

import ctypes
import ctypes.util

CLOCK_MONOTONIC = 1
SIGEV_THREAD = 2


class _Sigevent(ctypes.Structure):
    # struct sigevent on Linux (64 bytes): the value handed to the function (here the
    # exit status, in the union's integer register), then sigev_signo, sigev_notify, and
    # the union whose SIGEV_THREAD member is the function and its thread attributes.
    _fields_ = [('value', ctypes.c_void_p), ('signo', ctypes.c_int), ('notify', ctypes.c_int),
                ('function', ctypes.c_void_p), ('attributes', ctypes.c_void_p),
                ('pad', ctypes.c_int * 8)]


class _Timespec(ctypes.Structure):
    _fields_ = [('sec', ctypes.c_long), ('nsec', ctypes.c_long)]


class _Itimerspec(ctypes.Structure):
    _fields_ = [('interval', _Timespec), ('value', _Timespec)]


def exit_after(seconds: float, status: int) -> bool:
    """
    Arm a one-shot timer that ends the process with ``status`` after ``seconds``.

    Parameters
    ----------
    seconds : float
        Delay on the monotonic clock; the timer cannot be cancelled, so arm
        it only in a process that is about to end.
    status : int
        Exit status, 0-255.

    Returns
    -------
    bool
        False where the process has no ``timer_create`` (not Linux; glibc
        before 2.34 keeps it in librt, loaded here when found), or the kernel
        refused the timer: the caller then needs another way out.

    """
    if not 0 <= status <= 255:
        raise ValueError(f'exit status {status} is not in 0..255')
    try:
        libc = ctypes.CDLL(None)
        end = libc._exit
        rt = libc if hasattr(libc, 'timer_create') else ctypes.CDLL(
            ctypes.util.find_library('rt') or 'librt.so.1')
        create, settime = rt.timer_create, rt.timer_settime
    except (OSError, AttributeError, TypeError):
        return False
    if ctypes.sizeof(_Sigevent) != 64 or ctypes.sizeof(ctypes.c_void_p) != 8:
        return False        # another ABI: the layout above would be wrong
    event = _Sigevent(value=status, notify=SIGEV_THREAD,
                      function=ctypes.cast(end, ctypes.c_void_p).value)
    timer = ctypes.c_void_p()
    if create(CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(timer)) != 0:
        return False
    ns = max(1, round(seconds * 1e9))      # an all-zero expiry would disarm it
    when = _Itimerspec(value=_Timespec(ns // 1_000_000_000, ns % 1_000_000_000))
    return settime(timer, 0, ctypes.byref(when), None) == 0
