"""Run-time support: deadlines, progress, compiled CasADi functions and the solver call.

``budget`` (wall-clock budgets, hard stops on interrupt), ``progress`` (the progress lines of a
solve), ``compiled`` (CasADi code generation through the system C compiler, cached on disk) and
``solver`` (the Ipopt/Fatrop call, the public status map, typed solver statistics). It knows
nothing of arms or plans: it imports only the standard library, numerical packages and
``cpopt.runtime`` itself (never ``cpopt.io`` or anything above), and every other layer may
import it. Running a solve in a child process (``cpopt.isolate``) needs the whole pipeline, so
it lives with the application at the top.
"""
