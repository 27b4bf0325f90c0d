"""Shared machinery of the fan cloud VTK algorithms.

Imports numpy, ``vtkmodules`` and the core only (never pyvista): ParaView
5.11 ships VTK 9.2, which pyvista refuses.

* Parameters come from a table in :mod:`fancloud_vtk.params`: each becomes a
  Python property and a ``SetX``/``GetX`` pair that calls ``Modified()``
  only when the value really changes.
* VTK swallows exceptions raised inside ``RequestData``; the algorithm keeps
  the exception in ``last_error``, reports it through VTK's error output, and
  :func:`run` re-raises it for Python callers.
* Progress goes through ``UpdateProgress`` (PyVista's ``progress_bar`` and
  ParaView's progress bar listen to it); ``AbortExecute`` cancels.
"""

from __future__ import annotations

from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonCore import vtkCommand, vtkOutputWindow

from fancloud_vtk.params import Param


def _make_accessors(param: Param):
    def getter(self):
        return self._values[param.name]

    def setter(self, *args):
        # VTK style for vectors: SetWeights(1, 1, 50, 0) as well as SetWeights((1, 1, 50, 0))
        value = param.check(args[0] if len(args) == 1 else args)
        if self._values[param.name] != value:
            self._values[param.name] = value
            self.Modified()

    getter.__doc__ = f"{param.doc} (default: {param.default!r})."
    return getter, setter


def with_parameters(table: tuple[Param, ...]):
    """Class decorator: properties and ``SetX``/``GetX`` methods from a parameter table."""

    def decorate(cls):
        cls.PARAMETERS = table
        for param in table:
            getter, setter = _make_accessors(param)
            setattr(cls, param.name, property(getter, setter, doc=getter.__doc__))
            setattr(cls, "Get" + param.vtk_name, getter)
            setattr(cls, "Set" + param.vtk_name, setter)
        return cls

    return decorate


class FanCloudAlgorithm(VTKPythonAlgorithmBase):
    """Base of the fan cloud algorithms: parameters, errors, progress."""

    PARAMETERS: tuple[Param, ...] = ()

    def __init__(self, nInputPorts=1, inputType="vtkPointSet", nOutputPorts=1,
                 outputType="vtkPolyData", **params):
        VTKPythonAlgorithmBase.__init__(
            self, nInputPorts=nInputPorts, inputType=inputType,
            nOutputPorts=nOutputPorts, outputType=outputType,
        )
        self._values = {p.name: p.default for p in self.PARAMETERS}
        self.last_error: BaseException | None = None
        self._raised_by_run = False  # run() re-raises the error: it is not printed as well
        for name, value in params.items():
            if name not in self._values:
                raise TypeError(f"{type(self).__name__} has no parameter {name!r}")
            setattr(self, name, value)

    @property
    def parameters(self) -> dict:
        """Current parameter values by keyword."""
        return dict(self._values)

    def _progress(self, fraction: float, message: str = "") -> bool:
        """Progress callback for the core: report, and tell it to stop on abort."""
        self.SetProgressText(message)
        self.UpdateProgress(min(max(fraction, 0.0), 1.0))
        return bool(self.GetAbortExecute())

    def RequestData(self, request, inInfo, outInfo):
        self.last_error = None
        try:
            # an optional port with nothing connected gives None
            inputs = [self.GetInputData(inInfo, i, 0)
                      if inInfo[i].GetNumberOfInformationObjects() else None
                      for i in range(self.GetNumberOfInputPorts())]
            output = self.GetOutputData(outInfo, 0)
            result = self.execute(*inputs)
            output.ShallowCopy(result)
        except Exception as exc:  # VTK would swallow it: keep it for run()
            self.last_error = exc
            if not self._raised_by_run:  # ParaView's output window, a plain Update()
                vtkOutputWindow.GetInstance().DisplayErrorText(
                    f"{type(self).__name__}: {type(exc).__name__}: {exc}\n"
                )
            return 0
        return 1

    def execute(self, *inputs):
        """Compute the output data object from the input data objects."""
        raise TypeError(f"{type(self).__name__} defines no execute(): it is not an algorithm")


def run(algorithm, port: int = 0):
    """Update ``algorithm`` and return its output; re-raise an error from ``RequestData``.

    VTK only reports a failed update through its return value (and a second
    ``Update()`` returns success without running), so the algorithm is
    marked modified first when its last run failed. Its error is raised, not
    printed as well (a plain ``Update()``, as in ParaView, prints it to VTK's
    output window). A failure outside
    ``RequestData`` (no input connection, an input of the wrong type, a
    failing upstream algorithm) raises a ``RuntimeError`` with VTK's message
    instead of returning an empty output.
    """
    from .convert import _ErrorCatcher

    if algorithm.last_error is not None:
        algorithm.Modified()
    algorithms = _pipeline(algorithm)
    errors, pipeline_errors = _ErrorCatcher(), _ErrorCatcher()
    tags = [(alg, alg.AddObserver(vtkCommand.ErrorEvent, errors)) for alg in algorithms]
    tags += [
        (alg.GetExecutive(), alg.GetExecutive().AddObserver(vtkCommand.ErrorEvent, pipeline_errors))
        for alg in algorithms
    ]
    algorithm._raised_by_run = True
    try:
        ok = algorithm.Update()
    finally:
        algorithm._raised_by_run = False
        for obj, tag in tags:
            obj.RemoveObserver(tag)
    if algorithm.last_error is not None:
        raise algorithm.last_error
    # Update() returns the status on VTK >= 9.4 (None before: then VTK's errors decide)
    messages = errors.messages + pipeline_errors.messages
    failed = (not ok) if ok is not None else bool(messages)
    if failed:
        reason = messages[0] if messages else "see the VTK error output"
        raise RuntimeError(f"{type(algorithm).__name__}: the VTK pipeline update failed: {reason}")
    return algorithm.GetOutputDataObject(port)


def _pipeline(algorithm) -> list:
    """``algorithm`` and every algorithm upstream of it."""
    seen, todo, out = set(), [algorithm], []
    while todo:
        alg = todo.pop()
        if alg is None or id(alg) in seen:
            continue
        seen.add(id(alg))
        out.append(alg)
        for port in range(alg.GetNumberOfInputPorts()):
            for conn in range(alg.GetNumberOfInputConnections(port)):
                todo.append(alg.GetInputAlgorithm(port, conn))
    return out
