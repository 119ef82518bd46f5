"""Build support (setuptools, pyproject.toml ``[tool.setuptools.cmdclass]``): the editable install
(``pip install -e .``, as ``environment.txt`` does) installs the ``data-files`` too, as a regular
install does.

setuptools' ``editable_wheel`` means to copy data files into the editable wheel ("non-editable
files (data, headers, scripts) are written directly"), but asks the distribution for ``has_data()``,
which does not exist (its name is ``has_data_files``), so they are left out
(pypa/setuptools#3399).  This command gives the distribution that name before building; with a
setuptools that asks the right name it changes nothing.
"""

from setuptools.command.editable_wheel import editable_wheel


class EditableWheelWithData(editable_wheel):
    def run(self):
        dist = self.distribution
        if not hasattr(dist, "has_data"):
            dist.has_data = dist.has_data_files
        super().run()
