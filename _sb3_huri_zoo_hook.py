"""Start-up hook that makes ``rl_zoo3 train --algo huri`` work without a wrapper script.

RL Zoo has no plugin entry point, and its CLI checks ``--algo`` against ``rl_zoo3.ALGOS`` before it imports
``--gym-packages``: HuRi must be in ``ALGOS`` by the time ``rl_zoo3`` has finished importing. The
``sb3_huri_zoo_hook.pth`` file installed next to this module imports it at interpreter start-up.

Start-up cost is one small class: nothing is imported here but ``sys`` (no torch, no rl_zoo3, no sb3_huri).
A finder at the front of ``sys.meta_path`` watches for three RL Zoo modules and, right after one of them has
been executed, calls the matching function of ``sb3_huri.zoo`` (see ``_HOOKS``). Every other import costs
one dictionary lookup. Failures never propagate into the user's program: they are reported in one line on
stderr, pointing to the hook-free wrapper ``python -m sb3_huri.zoo``.
"""

import sys

# Module imported by RL Zoo -> functions of ``sb3_huri.zoo`` to call once that module is loaded.
_HOOKS = {
    "rl_zoo3": ("register_algorithms", "register_environments"),
    "rl_zoo3.hyperparams_opt": ("register_samplers",),
    "rl_zoo3.exp_manager": ("use_packaged_hyperparameters", "use_batched_zerith_env"),
}


def _run_hooks(module_name: str) -> None:
    for function in _HOOKS[module_name]:
        try:
            import sb3_huri.zoo

            getattr(sb3_huri.zoo, function)()
        except Exception as error:  # a start-up hook must never break the program that imported rl_zoo3
            sys.stderr.write(
                f"warning: sb3_huri.zoo.{function}() failed when {module_name} was imported "
                f"({type(error).__name__}: {error}); `python -m sb3_huri.zoo` shows the full error\n"
            )


class _LoaderThenHook:
    """Executes a module with its own loader, puts that loader back in place, then runs the hook."""

    def __init__(self, loader, module_name: str) -> None:
        self.loader = loader
        self.module_name = module_name

    def create_module(self, spec):
        create_module = getattr(self.loader, "create_module", None)
        return None if create_module is None else create_module(spec)

    def exec_module(self, module) -> None:
        module.__loader__ = module.__spec__.loader = self.loader
        self.loader.exec_module(module)
        _run_hooks(self.module_name)

    def __getattr__(self, name: str):
        # Anything else (get_code, is_package, ...) is the real loader's business.
        return getattr(self.loader, name)


class _RLZooFinder:
    """``sys.meta_path`` finder that only wraps the loader of the modules named in ``_HOOKS``."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in _HOOKS:
            return None
        for finder in sys.meta_path:
            find_spec = getattr(finder, "find_spec", None)
            if finder is self or find_spec is None:
                continue
            spec = find_spec(fullname, path, target)
            if spec is not None:
                if spec.loader is not None and hasattr(spec.loader, "exec_module"):
                    spec.loader = _LoaderThenHook(spec.loader, fullname)
                return spec
        return None


def _install() -> None:
    try:
        if not any(isinstance(finder, _RLZooFinder) for finder in sys.meta_path):
            sys.meta_path.insert(0, _RLZooFinder())
    except Exception:  # never fail interpreter start-up
        pass


_install()
