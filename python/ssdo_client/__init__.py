"""Python client of the ssdo service socket (``ssdo serve --socket PATH``).

Standard library only. The protocol it speaks: docs/service.md in the ssdo repository.

    from ssdo_client import Client, ServiceError

    with Client("/tmp/ssdo.sock", timeout=120) as client:
        client.check_protocol()
        result = client.process("/data/in/shot.0001.exr", method="gtao", preset="low")
        print(result.output, result.terms, result.times["total_ms"])
"""

from .client import (
    PROTOCOL_VERSION,
    Client,
    ProcessResult,
    ProtocolMismatchError,
    ReplyTimeout,
    ServiceError,
    SsdoError,
    TransportError,
)

__all__ = [
    "PROTOCOL_VERSION",
    "Client",
    "ProcessResult",
    "ProtocolMismatchError",
    "ReplyTimeout",
    "ServiceError",
    "SsdoError",
    "TransportError",
]
