"""The one result type every signature returns, so the verdict and the report treat them alike."""

from dataclasses import dataclass, field


@dataclass
class Signature:
    """
    One signature's answer on one record.

    ``stiction`` is True or False when the signature decides, None when it is
    undetermined or does not apply (``reason`` says which and why).  ``value``
    is compared with ``threshold`` in the direction the paper defines;
    ``details`` holds further JSON-able scalars; ``curves`` holds arrays for
    the report's figures and is never written to JSON.
    """

    name: str
    value: float | None
    threshold: float | None
    stiction: bool | None
    reason: str
    reference: str
    details: dict = field(default_factory=dict)
    curves: dict = field(default_factory=dict)

    def to_json(self):
        """Return the JSON-able part (everything but ``curves``)."""
        return {'value': self.value, 'threshold': self.threshold, 'stiction': self.stiction,
                'reason': self.reason, 'reference': self.reference, 'details': self.details}
